"""No silent garbage: every encoder refuses, in one line, a motion outside its numeric range or skeleton size."""

from __future__ import annotations

import numpy as np
import pytest

from mocapbench.codecs import CODECS, create
from mocapbench.motion import Motion, Skeleton
from mocapbench.synthetic import sinusoidal_motion

BASE = sinusoidal_motion(num_frames=24, seed=3)


def shifted(distance_cm: float) -> Motion:
    return Motion(BASE.skeleton, BASE.fps, BASE.root_positions + distance_cm, BASE.rotations, name="far")


@pytest.mark.parametrize("name", sorted(CODECS))
@pytest.mark.parametrize("factor", [1.0, 1e11, 1e294])
def test_a_motion_beyond_the_codec_range_is_refused_in_one_line(name, factor):
    codec = create(name, **CODECS[name].smoke_params)
    with pytest.raises(ValueError, match=r"reaches .* cm from the origin; this codec's numeric range is ±") as error:
        codec.encode(shifted(codec.max_coordinate_cm * factor))
    assert "\n" not in str(error.value)


# pga-ik is left out on purpose: its trajectory quantizer's step grows with the distance from the origin (its
# max_coordinate_cm comment gives the measured errors), so its smoke bound holds near the origin only.
@pytest.mark.parametrize("name", ["raw-zstd", "quant-delta-zstd", "svd", "mcb-linf"])
def test_a_motion_inside_the_range_still_round_trips(name):
    codec = create(name, **CODECS[name].smoke_params)
    distance = codec.max_coordinate_cm * 0.5
    motion = shifted(distance)
    decoded = codec.decode(codec.encode(motion))
    error = float(np.linalg.norm(decoded.positions - motion.positions(), axis=-1).max())
    # The smoke bound, plus float32 rounding at that distance for the codecs that store float32 (raw-zstd).
    bound = CODECS[name].smoke_max_error_cm + 1.2e-7 * distance
    assert error <= bound, f"{name}: L-inf {error:.4f} cm at half its range (bound {bound:.4f})"


def single_joint() -> Motion:
    skeleton = Skeleton(names=("root",), parents=np.array([-1]), offsets=np.zeros((1, 3)))
    return Motion(skeleton, BASE.fps, BASE.root_positions, BASE.rotations[:, :1], name="dot")


@pytest.mark.parametrize("name", sorted(CODECS))
def test_a_single_joint_skeleton_round_trips_or_is_refused_in_one_line(name):
    codec = create(name, **CODECS[name].smoke_params)
    motion = single_joint()
    try:
        data = codec.encode(motion)
    except (ValueError, RuntimeError) as error:
        assert "\n" not in str(error) and "joint" in str(error), f"{name}: {error}"
        assert codec.min_joints > 1 or "bases" in str(error), f"{name} refuses J=1 without saying so: {error}"
        return
    assert codec.min_joints == 1
    decoded = codec.decode(data)
    error = float(np.linalg.norm(decoded.positions - motion.positions(), axis=-1).max())
    assert error <= CODECS[name].smoke_max_error_cm, f"{name}: L-inf {error:.3f} cm on one joint"
