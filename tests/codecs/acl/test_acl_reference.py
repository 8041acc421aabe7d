"""mocapbench.benchmarks.acl.reference: the tools that compare `acl` with issue 14's independent ACL run.

The comparison arithmetic (bytes vs ratio, nearest point), the unit-change and jitter helpers, the variants'
wiring through the real ACL (a unit change of everything is a no-op; passing the precision unconverted is not),
and the parser of ACL's own quantization summary, on hand-written text and on what a patched copy of ACL prints.
"""

from __future__ import annotations

import numpy as np
import pytest

from mocapbench.benchmarks.acl import reference as ref
from mocapbench.datasets.cmu import CMU_CM_PER_UNIT
from mocapbench.io.bvh import read_bvh


def test_deviation_reads_the_ratio_as_bytes():
    point = {"ratio": 12.11, "linf_cm": 1.098, "mean_cm": 0.2, "p99_cm": 0.7}
    # The "bytes vs issue": reference ratio / our ratio - 1.
    assert ref._relative(point, "ratio", 13.54) == pytest.approx(13.54 / 12.11 - 1)
    assert ref._relative(point, "linf_cm", 1.26) == pytest.approx(1.098 / 1.26 - 1)
    assert ref.deviation(point, {"ratio": 13.54, "linf_cm": 1.26}) == pytest.approx(max(13.54 / 12.11 - 1, 1 - 1.098 / 1.26))
    assert ref.deviation(point, {"ratio": 13.54}) == pytest.approx(13.54 / 12.11 - 1)


def test_closest_orders_by_the_worst_number():
    reference = {"ratio": 10.0, "linf_cm": 1.0}
    points = [{"name": "a", "ratio": 10.0, "linf_cm": 1.3},   # 30 % off in L-inf
              {"name": "b", "ratio": 9.0, "linf_cm": 1.05},   # 11 % off in bytes
              {"name": "c", "ratio": 10.5, "linf_cm": 0.95}]  # 5 % off at worst
    assert [p["name"] for p in ref.closest(points, reference, count=2)] == ["c", "b"]


def test_scaled_changes_every_length(synthetic_motion):
    scaled = ref._scaled(synthetic_motion, 1 / CMU_CM_PER_UNIT)
    np.testing.assert_allclose(scaled.positions() * CMU_CM_PER_UNIT, synthetic_motion.positions(), atol=1e-9)
    np.testing.assert_allclose(scaled.skeleton.end_site_offsets * CMU_CM_PER_UNIT,
                               synthetic_motion.skeleton.end_site_offsets)


def test_jitter_is_tiny_and_keeps_the_quaternion_signs(synthetic_motion):
    jittered = ref._jittered(synthetic_motion, seed=0)
    change = np.abs(jittered.rotations - synthetic_motion.rotations).max()
    assert 0 < change < 1e-6
    assert np.all(np.sum(jittered.rotations * synthetic_motion.rotations, axis=-1) > 0)
    assert 0 < np.abs(jittered.positions() - synthetic_motion.positions()).max() < 1e-4
    assert not np.array_equal(ref._jittered(synthetic_motion, seed=1).rotations, jittered.rotations)


def test_points_sets(synthetic_motion):
    joints = synthetic_motion.num_joints
    ends = len(synthetic_motion.skeleton.end_site_parents)
    assert ends > 0
    assert ref._points(synthetic_motion, "joints").shape[1] == joints
    assert ref._points(synthetic_motion, "no-root").shape[1] == joints - 1
    assert ref._points(synthetic_motion, "joints+ends").shape[1] == joints + ends
    with pytest.raises(ValueError, match="Unknown point set"):
        ref._points(synthetic_motion, "bones")


def test_variants_change_what_they_say(acl_codec, synthetic_motion):
    acl_codec()  # skip or fail like every ACL test where ACL cannot be built
    motions = [synthetic_motion]
    variants = {v.name: v for v in ref.VARIANTS}
    base = ref.measure(motions, 0.1, 3.0)
    converted = ref.measure(motions, 0.1, 3.0, variants["BVH units, precision and shell converted"])
    unconverted = ref.measure(motions, 0.1, 3.0, variants["BVH units, precision p units (5.64p cm)"])
    ends = ref.measure(motions, 0.1, 3.0, variants["+ end sites measured"])
    # A unit change of everything is the same compression up to float32 rounding...
    assert converted["ratio"] == pytest.approx(base["ratio"], rel=0.02)
    assert converted["linf_cm"] == pytest.approx(base["linf_cm"], rel=0.2)
    # ... a precision left in the wrong unit is 5.6x coarser; end sites sit farther out on the same decode.
    assert unconverted["ratio"] > 1.3 * base["ratio"] and unconverted["linf_cm"] > 2 * base["linf_cm"]
    assert ends["ratio"] == base["ratio"] and ends["linf_cm"] >= base["linf_cm"]


_SUMMARY = """Quantizing segment 0...
Variable quantization optimization results:
0: 7 | 5 | 255 => 0.010000
1: 255 | 255 | 255 => 0.000000
2: 3 | 255 | 255 => 0.600000 !
Quantizing segment 1...
Variable quantization optimization results:
0: 9 | 5 | 255 => 0.020000
2: 5 | 255 | 255 => 0.700000 !
"""


def test_parse_quantization_summary():
    summary = ref.parse_quantization_summary(_SUMMARY, num_bones=3)
    assert summary["segments"].tolist() == [2, 2, 2]
    assert summary["over"].tolist() == [0, 0, 2]
    np.testing.assert_allclose(summary["mean_rotation_rate"], [8.0, 0.0, 4.0])  # 255 = constant, not counted


@pytest.mark.cmu
def test_debug_copy_prints_acls_summary(acl_codec, cmu_fixture_dir, tmp_path, monkeypatch):
    # Heavy (a fresh compile of the patched copy, ~25 s wall on the loaded CI box): on the real clip 09_06.
    acl_codec()
    motion = read_bvh(cmu_fixture_dir / "bvh" / "09_06.bvh", length_unit_cm=CMU_CM_PER_UNIT, drop_first_frame=True)
    root = ref.debug_acl_copy(tmp_path)
    monkeypatch.setenv("MOCAPBENCH_CACHE_DIR", str(tmp_path / "cache"))
    codec = ref.create("acl", precision_cm=0.5, shell_cm=3.0, acl_dir=root)
    log = str(tmp_path / "summary.txt")
    with ref._captured_stdout(log):
        codec.encode(motion)
    with open(log, encoding="utf-8") as handle:
        summary = ref.parse_quantization_summary(handle.read(), motion.num_joints)
    # 141 frames: ACL's segments of about 16 samples, each with a summary line per bone.
    assert summary["segments"][0] >= 5
    assert summary["mean_rotation_rate"].max() > 0


def test_debug_copy_refuses_an_acl_without_the_define(tmp_path):
    fake = tmp_path / "fake"
    (fake / "acl" / "includes" / "acl" / "compression" / "impl").mkdir(parents=True)
    (fake / "acl" / "includes" / "acl" / "compression" / "compress.h").write_text("")
    (fake / "acl" / "includes" / "acl" / "compression" / "impl" / "quantize.transform.h").write_text("// none\n")
    (fake / "rtm" / "includes" / "rtm").mkdir(parents=True)
    (fake / "rtm" / "includes" / "rtm" / "qvvf.h").write_text("")
    with pytest.raises(RuntimeError, match="define not found"):
        ref.debug_acl_copy(tmp_path / "out", str(fake))


def test_without_leaves_keeps_the_other_joints(synthetic_motion):
    skeleton = synthetic_motion.skeleton
    leaf = next(j for j in range(skeleton.num_joints) if not skeleton.children(j))
    reduced, keep = ref._without_leaves(synthetic_motion, [skeleton.names[leaf]])
    assert leaf not in keep and len(keep) == skeleton.num_joints - 1
    np.testing.assert_allclose(reduced.positions(), synthetic_motion.positions()[:, keep], atol=1e-9)
    inner = next(j for j in range(skeleton.num_joints) if skeleton.children(j))
    with pytest.raises(ValueError, match="is not a leaf joint"):
        ref._without_leaves(synthetic_motion, [skeleton.names[inner]])
