"""Every codec on a game rig (a ground root above a translated pelvis, tests/game_rig.py): a codec of joint positions
codes what the translation does to them; a rotation codec carries the translation (and scale) tracks or refuses the
motion in one line naming the joint, never dropping a track.

Learned codecs are fit on other takes of the same rig. The rig's Hips OFFSET lies 4.5 m from where the pelvis is on
any frame, so a codec that dropped the track would miss by metres: the bounds below are the codec's smoke bound.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pytest

from mocapbench import metrics
from mocapbench.codecs import CODECS, UNAVAILABLE, create

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from game_rig import game_rig_motion  # noqa: E402

NAMES = sorted(CODECS)


@pytest.fixture(scope="module")
def rig():
    return game_rig_motion(90, seed=0)


@pytest.fixture(scope="module")
def training():
    return [game_rig_motion(120, seed=seed) for seed in (11, 12)]


def _carries(name: str, track: str) -> bool:
    return not CODECS[name].codes_rotations or track in CODECS[name].carries_tracks


@pytest.mark.parametrize("name", NAMES)
def test_a_game_rig_round_trips_or_is_refused_naming_the_joint(name, rig, training):
    codec = create(name, **CODECS[name].smoke_params)
    if not _carries(name, "translations"):
        with pytest.raises(ValueError, match=rf"^{name}: joint 'Hips' moves relative to its parent"):
            codec.encode(rig)
        return
    codec.fit(training)
    data = codec.encode(rig)
    decoded = create(name, **CODECS[name].smoke_params).fit(training).decode(data)
    error = metrics.max_joint_error(rig.positions(), decoded.positions)
    assert error <= CODECS[name].smoke_max_error_cm, f"{name}: L-inf {error:.4f} cm"
    if CODECS[name].codes_rotations:
        assert list(decoded.motion.moving_joints()) == [1]
        np.testing.assert_allclose(decoded.motion.positions(), decoded.positions, atol=1e-9)


@pytest.mark.parametrize("name", [n for n in NAMES if CODECS[n].codes_rotations])
def test_a_scale_track_is_carried_or_refused_naming_the_joint(name, training):
    motion = game_rig_motion(60, seed=1, scaled=True)
    codec = create(name, **CODECS[name].smoke_params)
    if not _carries(name, "translations") or not _carries(name, "scales"):
        with pytest.raises(ValueError, match=rf"^{name}: joint '(Hips|LowerArm_L)' (moves|is scaled)"):
            codec.encode(motion)
        return
    codec.fit(training)
    decoded = codec.decode(codec.encode(motion))
    assert metrics.max_joint_error(motion.positions(), decoded.positions) <= CODECS[name].smoke_max_error_cm
    assert list(decoded.motion.scaled_joints()) == [8]
    # The hand's end site is carried by the stretched forearm's children: within the bound only if the scale is.
    ends = np.linalg.norm(motion.end_site_positions() - decoded.motion.end_site_positions(), axis=-1)
    assert ends[:, 1].max() <= 2 * CODECS[name].smoke_max_error_cm + 0.5


@pytest.mark.parametrize("name", ["mcb-rot", "acl", "quant-rot-zstd"])
def test_a_game_rig_bvh_with_position_channels_on_every_joint(name, tmp_path):
    """The rig as a MotionBuilder export writes it (``CHANNELS 6`` on every joint), read back and coded: the joints
    whose channels repeat their OFFSET cost nothing, the pelvis is carried, the bound holds."""
    from mocapbench.io.bvh import read_bvh, write_bvh

    if name not in CODECS:
        if os.environ.get("CI", "").strip().lower() in ("true", "1"):  # CI has ../shared and a compiler
            pytest.fail(f"{name} is unavailable here: {UNAVAILABLE.get(name)}")
        pytest.skip(f"{name} is unavailable here: {UNAVAILABLE.get(name)}")
    path = write_bvh(game_rig_motion(60, seed=9), tmp_path / "rig.bvh", position_channels="all")
    assert path.read_text().count("CHANNELS 6") == 22
    motion = read_bvh(path)
    assert list(motion.moving_joints()) == [1]
    codec = create(name, **CODECS[name].smoke_params)
    decoded = codec.decode(codec.encode(motion))
    assert metrics.max_joint_error(motion.positions(), decoded.positions) <= CODECS[name].smoke_max_error_cm
    assert list(decoded.motion.moving_joints()) == [1]
