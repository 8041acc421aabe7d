"""ACL's shell (virtual-vertex) error: a hand-computed case, its link to the joint error, its error paths."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from mocapbench import metrics
from mocapbench.motion import Motion, Skeleton

RZ90 = Rotation.from_euler("z", 90, degrees=True)


def _chain_motion(root_rotation: Rotation) -> Motion:
    """Root at the origin, one child 10 cm along the root's x axis, identity local rotation on the child."""
    skeleton = Skeleton(names=("root", "child"), parents=np.array([-1, 0]), offsets=np.array([[0, 0, 0], [10.0, 0, 0]]))
    rotations = np.stack([root_rotation.as_quat(), [0, 0, 0, 1.0]])[None]
    return Motion(skeleton, 120.0, np.zeros((1, 3)), rotations)


def test_one_joint_by_hand():
    # Reference: identity at the origin. Decoded: 90 degrees about z and 1 cm along x. Shell d = 3 cm:
    # x vertex (3,0,0) -> (1,3,0): sqrt(13); y vertex (0,3,0) -> (-2,0,0): sqrt(13); z vertex (0,0,3) -> (1,0,3): 1.
    ref_r, dec_r = np.eye(3)[None, None], RZ90.as_matrix()[None, None]
    ref_p, dec_p = np.zeros((1, 1, 3)), np.array([[[1.0, 0, 0]]])
    assert metrics.shell_errors(ref_r, ref_p, dec_r, dec_p, 3.0)[0, 0] == pytest.approx(np.sqrt(13.0), abs=1e-12)
    assert metrics.shell_errors(ref_r, ref_p, dec_r, dec_p, 0.0)[0, 0] == pytest.approx(1.0, abs=1e-12)


def test_chain_by_hand_through_forward_kinematics():
    # Decoded root turned 90 degrees about z: the child moves from (10,0,0) to (0,10,0) and turns too.
    # Root: x and y vertices move by 3*sqrt(2). Child: x vertex (13,0,0) -> (0,13,0): 13*sqrt(2) (y: sqrt(218),
    # z: sqrt(200)).
    errors = metrics.motion_shell_errors(_chain_motion(Rotation.identity()), _chain_motion(RZ90), 3.0)
    np.testing.assert_allclose(errors, [[3 * np.sqrt(2), 13 * np.sqrt(2)]], atol=1e-9)


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 2), st.floats(0.0, 50.0))  # Rotation.random also takes seed + 1
def test_shell_error_is_joint_error_at_zero_and_grows_with_distance(seed, shell):
    rng = np.random.default_rng(seed)
    ref_r = Rotation.random(12, random_state=seed).as_matrix().reshape(3, 4, 3, 3)
    dec_r = (Rotation.random(12, random_state=(seed + 1) % 2**32) ** 0.01).as_matrix().reshape(3, 4, 3, 3) @ ref_r
    ref_p, dec_p = rng.normal(size=(3, 4, 3)), rng.normal(size=(3, 4, 3))
    at_zero = metrics.shell_errors(ref_r, ref_p, dec_r, dec_p, 0.0)
    np.testing.assert_allclose(at_zero, metrics.joint_errors(ref_p, dec_p), atol=1e-12)
    # Each vertex error is within d * ||R_ref - R_dec|| of the joint error (triangle inequality).
    spread = shell * np.linalg.norm(ref_r - dec_r, axis=-2).max(axis=-1)
    at_shell = metrics.shell_errors(ref_r, ref_p, dec_r, dec_p, shell)
    assert np.all(at_shell <= at_zero + spread + 1e-9)
    assert np.all(at_shell >= spread - at_zero - 1e-9)


@pytest.mark.parametrize(
    "change, match",
    [
        ({"decoded_positions": np.zeros((2, 2, 3))}, "decoded_positions.*shape"),
        ({"reference_matrices": np.zeros((1, 2, 3))}, "reference_matrices.*shape"),
        ({"decoded_matrices": np.full((1, 2, 3, 3), np.nan)}, "decoded_matrices.*non-finite"),
        ({"shell_cm": -1.0}, "shell_cm.*>= 0"),
    ],
)
def test_bad_input_names_the_argument(change, match):
    args = {
        "reference_matrices": np.tile(np.eye(3), (1, 2, 1, 1)),
        "reference_positions": np.zeros((1, 2, 3)),
        "decoded_matrices": np.tile(np.eye(3), (1, 2, 1, 1)),
        "decoded_positions": np.zeros((1, 2, 3)),
        "shell_cm": 3.0,
    }
    args.update(change)
    with pytest.raises(ValueError, match=match):
        metrics.shell_errors(**args)
