"""mcb-rot error budgets: the vectorized chain lengths are the one-joint-at-a-time sums, bit for bit."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from mocapbench.codecs.mcb_rot.budgets import _chains, joint_budgets
from mocapbench.motion import Skeleton
from mocapbench.synthetic import cmu_like_skeleton


def _reference_chains(skeleton: Skeleton) -> tuple[np.ndarray, np.ndarray]:
    """``C[a, k] = C[a, parent(k)] + |offset_k|`` joint by joint (the definition, top-down sums)."""
    num_joints = skeleton.num_joints
    bones = np.sqrt(np.sum(skeleton.offsets**2, axis=1))
    chain = np.zeros((num_joints, num_joints))
    ancestors = np.zeros((num_joints, num_joints), dtype=bool)
    for k in range(1, num_joints):
        parent = skeleton.parents[k]
        ancestors[k] = ancestors[parent]
        ancestors[k, parent] = True
        for a in np.flatnonzero(ancestors[k]):
            chain[a, k] = chain[a, parent] + bones[k]
    return chain, ancestors


@st.composite
def skeletons(draw) -> Skeleton:
    num_joints = draw(st.integers(1, 40))
    parents = [-1] + [draw(st.integers(max(k - 3, 0), k - 1)) for k in range(1, num_joints)]
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    offsets = rng.normal(size=(num_joints, 3)) * rng.uniform(0.1, 40.0, size=(num_joints, 1))
    offsets[rng.random(num_joints) < 0.15] = 0.0  # zero-length bones
    return Skeleton(names=tuple(f"j{k}" for k in range(num_joints)), parents=np.array(parents), offsets=offsets)


@settings(max_examples=60, deadline=None)
@given(skeletons())
def test_chains_equal_the_joint_by_joint_sums_bit_for_bit(skeleton):
    chain, ancestors = _chains(skeleton)
    expected_chain, expected_ancestors = _reference_chains(skeleton)
    np.testing.assert_array_equal(ancestors, expected_ancestors)
    assert chain.tobytes() == expected_chain.tobytes()  # the encoder's streams depend on these exact floats


def test_budgets_of_a_cmu_rig_keep_every_chain_within_the_bound():
    skeleton = cmu_like_skeleton()
    budgets = joint_budgets(skeleton, 0.1, 0.05, np.deg2rad(1.0))
    chain, ancestors = _reference_chains(skeleton)
    worst = budgets.root_cm + (budgets.rotation_rad[:, None] * chain).sum(axis=0)  # per joint, the error bound
    assert worst.max() <= 0.1 * (1 + 1e-12)
    assert worst.max() >= 0.1 * (1 - 1e-9)  # the budgets use the whole bound
    np.testing.assert_array_equal(budgets.ancestors, ancestors)
