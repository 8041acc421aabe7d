"""Geodesic IK (Tournier et al. 2008 §3.4, §3.6): forward model, analytic Jacobian, LM recovery of exact poses."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mocapbench.codecs import create
from mocapbench.codecs.pga.codec import select_end_joints
from mocapbench.codecs.pga.geodesics import fit_pga, geodesic_poses
from mocapbench.codecs.pga.ik import GeodesicIK, from_root_frame, to_root_frame
from mocapbench.codecs.pga.model_motion import geodesic_model_motion
from mocapbench.motion import Motion
from mocapbench.synthetic import cmu_like_skeleton


@pytest.fixture(scope="module")
def random_ik():
    skeleton = cmu_like_skeleton()
    rng = np.random.default_rng(5)
    mean = Rotation.from_rotvec(rng.normal(scale=0.5, size=(30, 3))).as_quat()
    directions = rng.normal(size=(7, 30, 3))
    directions /= np.linalg.norm(directions.reshape(7, -1), axis=1)[:, None, None]
    return GeodesicIK(skeleton, mean, directions, select_end_joints(skeleton)), mean, directions


def test_forward_matches_motion_fk(random_ik):
    ik, mean, directions = random_ik
    x = np.random.default_rng(0).normal(size=7)
    inner = geodesic_poses(mean, directions, x).as_quat()
    quats = np.concatenate([[[0, 0, 0, 1]], inner])[None]
    positions = Motion(ik.skeleton, 120.0, np.zeros((1, 3)), quats).positions()[0]
    np.testing.assert_allclose(ik.forward(x), positions[list(ik.end_joints)], rtol=0, atol=1e-10)


@pytest.mark.parametrize("k", [1, 2, 7, 12])
def test_jacobian_matches_central_differences(k):
    skeleton = cmu_like_skeleton()
    rng = np.random.default_rng(k)
    mean = Rotation.from_rotvec(rng.normal(scale=0.5, size=(30, 3))).as_quat()
    directions = rng.normal(size=(k, 30, 3))
    directions /= np.linalg.norm(directions.reshape(k, -1), axis=1)[:, None, None]
    ik = GeodesicIK(skeleton, mean, directions, select_end_joints(skeleton))
    for x in rng.normal(scale=0.7, size=(3, k)):
        analytic = ik.jacobian(x)
        h = 1e-6
        numeric = np.stack(
            [(ik.forward(x + h * e) - ik.forward(x - h * e)).ravel() / (2 * h) for e in np.eye(k)], axis=1
        )
        assert analytic.shape == (3 * len(ik.end_joints), k)
        assert np.max(np.abs(analytic - numeric)) < 1e-5 * max(1.0, np.max(np.abs(numeric)))


def test_root_frame_round_trip():
    rng = np.random.default_rng(2)
    rot = Rotation.from_rotvec(rng.normal(size=(10, 3))).as_quat()
    root = rng.normal(scale=100, size=(10, 3))
    points = rng.normal(scale=100, size=(10, 5, 3))
    local = to_root_frame(rot, root, points)
    np.testing.assert_allclose(from_root_frame(rot, root, local), points, atol=1e-10)
    np.testing.assert_allclose(np.linalg.norm(local, axis=-1), np.linalg.norm(points - root[:, None], axis=-1))


def test_lm_recovers_exact_end_joints_from_lossless_targets():
    motion, mean, directions, coords = geodesic_model_motion()
    skeleton = motion.skeleton
    ends = select_end_joints(skeleton)
    targets = to_root_frame(motion.rotations[:, 0], motion.root_positions, motion.positions()[:, ends])
    model = fit_pga(motion.rotations[:, 1:], directions.shape[0])
    ik = GeodesicIK(skeleton, model.mean, model.directions, ends)
    solved = ik.solve_sequence(targets, lam=1.0, iterations=5)
    reached = np.stack([ik.forward(x) for x in solved])
    assert np.max(np.linalg.norm(reached - targets, axis=-1)) < 0.1  # cm
    # Not a trivial pass: the targets do move by tens of cm in the root frame.
    assert np.ptp(targets[:, 0, 1]) > 10.0


@pytest.mark.parametrize("unit_cm, bound_cm", [(1.0, 0.1), (None, 0.2)])
def test_codec_with_lossless_trajectories_reproduces_end_joints(unit_cm, bound_cm):
    # lambda = 1 in cm^2 (unit 1 cm) matches the end joints to < 0.1 cm; the default reading of the paper's
    # lambda = 1 (CMU units, 31.9 cm^2) lags a fast motion (coordinates moving ~0.09 rad/frame) by ~0.1 cm.
    motion, _, directions, _ = geodesic_model_motion(num_frames=129)
    params = dict(
        num_geodesics=directions.shape[0],
        root_levels_dropped=0,
        end_levels_dropped=0,
        trajectory_bits=24,
        model_bits=24,
        lm_iterations=5,
    )
    if unit_cm is not None:
        params["ik_length_unit_cm"] = unit_cm
    data = create("pga-ik", **params).encode(motion)
    decoded = create("pga-ik", **params).decode(data)
    ends = select_end_joints(motion.skeleton)
    errors = np.linalg.norm(decoded.positions[:, ends] - motion.positions()[:, ends], axis=-1)
    assert np.max(errors) < bound_cm
    # On an exact model the rest of the body follows too.
    assert np.max(np.linalg.norm(decoded.positions - motion.positions(), axis=-1)) < 0.5


def test_bad_model_shapes_are_named():
    skeleton = cmu_like_skeleton()
    with pytest.raises(ValueError, match="Expected `mean` of shape \\(30, 4\\)"):
        GeodesicIK(skeleton, np.zeros((29, 4)), np.zeros((2, 30, 3)), [4])
    with pytest.raises(ValueError, match="`end_joints` must be distinct"):
        GeodesicIK(skeleton, np.tile([0, 0, 0, 1.0], (30, 1)), np.zeros((2, 30, 3)), [4, 4])
    ik = GeodesicIK(skeleton, np.tile([0, 0, 0, 1.0], (30, 1)), np.ones((2, 30, 3)), [4])
    with pytest.raises(ValueError, match="targets"):
        ik.solve_sequence(np.zeros((3, 2, 3)), 1.0, 2)
