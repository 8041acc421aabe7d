"""The rate search reads its clip's forward kinematics once: the same positions, the same streams, fewer FK runs."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mocapbench import motion as motion_module
from mocapbench.codecs import create
from mocapbench.ratesearch import known_kinematics, search
from mocapbench.synthetic import rig_motion


@pytest.fixture
def fk_calls(monkeypatch):
    """The number of forward-kinematics block runs so far (a list: its length)."""
    calls = []
    real = motion_module._forward_kinematics

    def counted(*args, **kwargs):
        calls.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(motion_module, "_forward_kinematics", counted)
    return calls


def test_known_kinematics_gives_the_motions_values_once_and_copies(fk_calls):
    clip = rig_motion(num_joints=16, num_frames=50, seed=1)
    expected_positions = clip.positions()
    expected_matrices, _ = clip.global_transforms()
    expected_ends = clip.end_site_positions()
    known = known_kinematics(clip)
    assert known_kinematics(known) is known and known.name == clip.name and known.rotations is clip.rotations
    fk_calls.clear()
    first = known.positions()
    first[:] = 0.0  # a caller that scribbles on its copy changes nothing kept
    np.testing.assert_array_equal(known.positions(), expected_positions)
    matrices, positions = known.global_transforms()
    np.testing.assert_array_equal(matrices, expected_matrices)
    np.testing.assert_array_equal(positions, expected_positions)
    np.testing.assert_array_equal(known.end_site_positions(), expected_ends)
    assert len(fk_calls) == 2  # positions once, transforms once, whatever was asked after


def test_a_motion_made_from_it_computes_its_own_kinematics():
    clip = rig_motion(num_joints=16, num_frames=50, seed=1)
    known = known_kinematics(clip)
    known.positions()
    still = dataclasses.replace(known, rotations=clip.rotations[:, ::-1].copy())  # other rotations
    np.testing.assert_array_equal(still.positions(), dataclasses.replace(clip, rotations=still.rotations).positions())
    assert not np.array_equal(still.positions(), known.positions())
    np.testing.assert_array_equal(known.slice(10, 20).positions(), clip.slice(10, 20).positions())


@pytest.mark.parametrize("name", ["dct-spatial-clip", "quant-rot-zstd", "mcb-linf"])
def test_the_search_codes_the_same_stream_with_one_forward_kinematics_of_its_clip(name, fk_calls):
    clip = rig_motion(num_joints=18, num_frames=60, seed=2)
    fk_calls.clear()
    result = search(name, clip, 1.0)
    runs_per_pass = len(range(0, clip.num_frames, motion_module._FK_BLOCK_FRAMES))
    decoded_passes = result.tries if create(name).codes_rotations else 0  # a decoder's own FK of what it decoded
    assert len(fk_calls) == runs_per_pass * (1 + decoded_passes)
    fresh = create(name, **result.settings)
    assert fresh.encode(clip) == result.data  # the stream the search keeps is the one a fresh encode writes
    assert result.encode_stats == fresh.last_encode_stats and result.encode_cpu_s >= 0 and result.tries >= 1


@pytest.mark.parametrize("name", ["svd", "dct-spatial-clip", "quant-delta-zstd", "raw-zstd"])
def test_searches_in_lockstep_take_each_clips_own_steps(name, monkeypatch):
    from mocapbench.codecs.base import Codec
    from mocapbench.ratesearch import search_many

    clips = [rig_motion(num_joints=joints, num_frames=frames, seed=seed)
             for joints, frames, seed in ((18, 40, 1), (18, 40, 2), (24, 55, 3))]
    alone = [search(name, clip, 1.0) for clip in clips]
    calls = []
    real = Codec.encode_many

    def counted(self, motions):
        calls.append(len(motions))
        return real(self, motions)

    monkeypatch.setattr(Codec, "encode_many", counted)
    together = search_many(name, clips, 1.0)
    for one, other in zip(alone, together):
        assert (other.data, other.settings, other.tries, other.met) == (one.data, one.settings, one.tries, one.met)
        assert other.max_error_cm == one.max_error_cm and other.encode_stats == one.encode_stats
    assert sum(calls) == sum(result.tries for result in alone)  # every try once, clips of one setting together
    assert max(calls) > 1  # the first round's setting is the same for every clip
