"""A job hands its clips to a codec that encodes many at once and shares the batch's time by frames."""

from __future__ import annotations

import dataclasses

import numpy as np

from mocapbench.codecs import create
from mocapbench.experiments import run
from mocapbench.experiments.evaluate import evaluate
from mocapbench.synthetic import sinusoidal_motion


class _Batching:
    """raw-zstd seen through encode_many, counting calls."""

    encodes_many = True

    def __init__(self):
        self.codec = create("raw-zstd")
        self.calls = []

    def encode_many(self, motions):
        self.calls.append([m.name for m in motions])
        return self.codec.__class__.encode_many(self.codec, motions)


def test_clips_go_in_batches_of_bounded_frames_and_share_the_time_by_frames(monkeypatch):
    monkeypatch.setattr(run, "BATCH_FRAMES", 250)
    motions = [dataclasses.replace(sinusoidal_motion(num_frames=f, seed=i), name=f"clip{i}")
               for i, f in enumerate((100, 100, 40, 200))]
    codec = _Batching()
    out = list(run._encode_batches(codec, iter(motions), None))
    assert codec.calls == [["clip0", "clip1", "clip2"], ["clip3"]]
    assert [m.name for m, _ in out] == ["clip0", "clip1", "clip2", "clip3"]
    first = [encoded[2] for _, encoded in out[:3]]
    assert first[0].cpu_s == first[1].cpu_s and np.isclose(first[2].cpu_s, first[0].cpu_s * 40 / 100)
    assert all(t.repeats == 1 and t.warmup == 0 for t in first)
    # The rows are the codec's own streams, measured as usual.
    row = evaluate(codec.codec, out[0][0], encoded=out[0][1])
    assert row["bitstream_bytes"] == len(codec.codec.encode(motions[0]))
    assert row["encode_repeats"] == 1


def test_a_refused_clip_is_handed_back_as_its_error():
    codec = _Batching()
    good = sinusoidal_motion(num_frames=20, seed=1)
    bad = dataclasses.replace(good, root_positions=good.root_positions + 1e9)  # outside raw-zstd's numeric range
    out = list(run._encode_batches(codec, iter([bad, sinusoidal_motion(num_frames=20, seed=2)]), None))
    assert isinstance(out[0][1], ValueError) and isinstance(out[1][1], tuple)
