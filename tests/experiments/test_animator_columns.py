"""What animators see in the results rows: a rotation codec keeps every bone, a positions codec does not."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from mocapbench.codecs import create
from mocapbench.experiments.animator_metrics import ANIMATOR_COLUMNS, pool_animator_columns
from mocapbench.experiments.evaluate import TimingSettings, evaluate
from mocapbench.synthetic import sinusoidal_motion

ONCE = TimingSettings(repeats=1, warmup=0)


@pytest.fixture(scope="module")
def motion():
    return sinusoidal_motion(num_frames=90, seed=4)


def test_a_rotation_codec_keeps_every_bone_length(motion):
    row = evaluate(create("quant-rot-zstd", rotation_bits=8), motion, timing=ONCE)
    assert set(ANIMATOR_COLUMNS) <= set(row)
    assert row["bone_len_max_dev_cm"] < 1e-9  # rigid by construction: only float rounding
    assert 0 < row["rot_mean_err_deg"] <= row["rot_max_err_deg"] < 2.0  # 8 bits: coarse, not wild
    assert row["end_site_max_err_cm"] > 0 and row["end_site_mean_err_cm"] <= row["end_site_max_err_cm"]
    assert row["accel_rms_err_cm_s2"] > 0 and row["accel_max_err_cm_s2"] >= row["accel_rms_err_cm_s2"]


def test_a_positions_codec_stretches_bones_within_twice_its_error(motion):
    row = evaluate(create("mcb-linf", eps_cm=1.0), motion, timing=ONCE)
    assert 0 < row["bone_len_max_dev_cm"] <= 2 * row["max_err_cm"] + 1e-9
    assert np.isnan(row["rot_max_err_deg"]) and np.isnan(row["end_site_max_err_cm"])  # returns no rotations


def test_float32_positions_show_only_rounding(motion):
    row = evaluate(create("raw-zstd"), motion, timing=ONCE)
    # float32 rounds a 100 cm coordinate by ~4e-6 cm; a second difference at 120 fps multiplies by 4 * 14400.
    assert row["accel_max_err_cm_s2"] < 2.0 and row["bone_len_max_dev_cm"] < 1e-4
    if row["foot_contacts"]:
        assert row["foot_slide_mean_cm"] == pytest.approx(row["foot_slide_ref_mean_cm"], abs=1e-3)


def test_pooling_weighs_means_and_keeps_the_worst_clip():
    rows = pd.DataFrame([
        {"dataset": "d", "codec": "c", "config_hash": "h", "frames": 102, "accel_rms_err_cm_s2": 3.0,
         "accel_max_err_cm_s2": 9.0, "foot_contacts": 1, "foot_slide_mean_cm": 2.0, "bone_len_mean_dev_cm": 1.0,
         "rot_max_err_deg": np.nan},
        {"dataset": "d", "codec": "c", "config_hash": "h", "frames": 302, "accel_rms_err_cm_s2": 1.0,
         "accel_max_err_cm_s2": 4.0, "foot_contacts": 3, "foot_slide_mean_cm": 6.0, "bone_len_mean_dev_cm": 0.0,
         "rot_max_err_deg": np.nan},
    ])
    pooled = pool_animator_columns(rows, ["dataset", "codec", "config_hash"]).iloc[0]
    assert pooled["accel_max_err_cm_s2"] == 9.0
    assert pooled["accel_rms_err_cm_s2"] == pytest.approx(np.sqrt((9 * 100 + 1 * 300) / 400))
    assert pooled["foot_contacts"] == 4 and pooled["foot_slide_mean_cm"] == pytest.approx((2 + 18) / 4)
    assert pooled["bone_len_mean_dev_cm"] == pytest.approx(102 / 404)
    assert np.isnan(pooled["rot_max_err_deg"])
