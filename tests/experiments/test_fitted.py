"""Learned state: fit once per (codec config, training set) for the whole sweep; the shipped model where it fits."""

from __future__ import annotations

import numpy as np

from mocapbench.codecs import create
from mocapbench.codecs.mcb_linf.model import load_default_model
from mocapbench.experiments import fitted
from mocapbench.synthetic import sinusoidal_motion

SYNTHETIC = {"name": "synthetic", "kind": "synthetic", "clips": {"seeds": [1], "num_frames": 60},
             "train": {"clips": {"seeds": [11, 12], "num_frames": 60}}}
CMU_TEST = {"name": "cmu_test", "kind": "cmu", "split": "cmu_test", "data_dir": "/nowhere",
            "train": {"split": "cmu_train"}}


def _no_training():
    raise AssertionError("the training set must not be read")


def test_mcb_linf_on_cmu_train_uses_the_shipped_model_without_reading_data(tmp_path):
    codec = create("mcb-linf", eps_cm=2.0)
    info = fitted.prepare(codec, CMU_TEST, tmp_path, load_training=_no_training)
    assert info["fit_source"] == "shipped" and info["fit_s"] == 0.0
    motion = sinusoidal_motion(num_frames=60, seed=1)
    stream = codec.encode(motion)
    # Its streams decode with a fresh codec holding only the shipped model (same tag).
    assert np.abs(create("mcb-linf", eps_cm=2.0).decode(stream).positions - motion.positions()).max() <= 2.0
    assert codec.model_bytes == load_default_model().stored_bytes
    assert not list(tmp_path.iterdir())


def test_fit_settings_other_than_the_shipped_ones_fit_once_and_every_config_shares_it(tmp_path):
    calls = []

    def training():
        calls.append(1)
        return [sinusoidal_motion(num_frames=60, seed=s) for s in (11, 12)]

    first = create("mcb-linf", eps_cm=1.0)
    info = fitted.prepare(first, SYNTHETIC, tmp_path, load_training=training)
    assert info["fit_source"] == "fitted" and len(calls) == 1
    second = create("mcb-linf", eps_cm=3.0)  # another step, same fit settings and training set
    info2 = fitted.prepare(second, SYNTHETIC, tmp_path, load_training=training)
    assert info2["fit_source"] == "sweep" and info2["fit_file"] == info["fit_file"] and len(calls) == 1
    assert second._model.tag == first._model.tag != load_default_model().tag
    other = create("mcb-linf", eps_cm=1.0, clip_frames=240)  # a fit setting changes: its own state
    assert fitted.prepare(other, SYNTHETIC, tmp_path, load_training=training)["fit_file"] != info["fit_file"]
    assert len(calls) == 2


def test_configs_that_learn_nothing_are_not_fit(tmp_path):
    for codec in (create("mcb-linf", representation="bone", entropy="bands"), create("lsdt-frame"),
                  create("quant-delta-zstd")):
        assert fitted.prepare(codec, SYNTHETIC, tmp_path, load_training=_no_training)["fit_source"] == "none"


def test_lsdt_bases_fit_once_are_loaded_back_exactly(tmp_path):
    def training():
        return [sinusoidal_motion(num_frames=40, seed=11)]

    a = create("lsdt-frame", basis="fit", sparsity=5, train_iterations=3)
    assert fitted.prepare(a, SYNTHETIC, tmp_path, load_training=training)["fit_source"] == "fitted"
    b = create("lsdt-frame", basis="fit", sparsity=5, train_iterations=3, step_cm=2.0)
    assert fitted.prepare(b, SYNTHETIC, tmp_path, load_training=training)["fit_source"] == "sweep"
    assert np.array_equal(a._bases(31), b._bases(31))
