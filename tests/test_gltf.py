"""glTF 2.0 / GLB in and out: the written file, evaluated by an independent reader, has the motion's joint positions."""

from __future__ import annotations

import base64

import numpy as np
import pygltflib
import pytest
from scipy.spatial.transform import Rotation, Slerp

from mocapbench import metrics
from mocapbench.cli import main
from mocapbench.io import read_bvh
from mocapbench.io.gltf import read_gltf, write_gltf
from mocapbench.motion import MotionFormatError
from mocapbench.synthetic import rig_motion, user_case, write_case_bvh
from mocapbench.synthetic.game import game_rig_motion

_DTYPES = {5126: np.float32, 5123: np.uint16, 5125: np.uint32}
_WIDTHS = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}
_Z_TO_Y = Rotation.from_euler("X", -90, degrees=True).as_matrix()


def _blob(gltf: pygltflib.GLTF2) -> bytes:
    uri = gltf.buffers[0].uri
    return gltf.binary_blob() if uri is None else base64.b64decode(uri.split(",", 1)[1])


def _accessor(gltf, blob, index) -> np.ndarray:
    accessor = gltf.accessors[index]
    view = gltf.bufferViews[accessor.bufferView]
    dtype, width = _DTYPES[accessor.componentType], _WIDTHS[accessor.type]
    start = (view.byteOffset or 0) + (accessor.byteOffset or 0)
    return np.frombuffer(blob, dtype=dtype, count=accessor.count * width, offset=start).reshape(accessor.count, width)


def _trs(translation, rotation, scale) -> np.ndarray:
    matrix = np.eye(4)
    matrix[:3, :3] = Rotation.from_quat(rotation).as_matrix() * np.asarray(scale)
    matrix[:3, 3] = translation
    return matrix


def _independent_joint_positions(path) -> np.ndarray:
    """World positions (F, J, 3) of the skin's joints at every key, from pygltflib's parse and 4x4 matrices only."""
    return _independent_world_positions(path)[0]


def _independent_world_positions(path) -> tuple[np.ndarray, np.ndarray]:
    """World positions at every key of the skin's joints (F, J, 3) and of the childless, mesh-less non-joint nodes
    under them, the end sites (F, E, 3, in node order), from pygltflib's parse and 4x4 matrices (T R S) only."""
    gltf = pygltflib.GLTF2.load(str(path))
    blob = _blob(gltf)
    animation = gltf.animations[0]
    keyed = {}
    num_keys = None
    for channel in animation.channels:
        sampler = animation.samplers[channel.sampler]
        values = _accessor(gltf, blob, sampler.output).astype(np.float64)
        if sampler.interpolation == "CUBICSPLINE":
            values = values.reshape(-1, 3, values.shape[1])[:, 1]
        keyed[(channel.target.node, channel.target.path)] = values
        num_keys = len(values)
    parents = {child: index for index, node in enumerate(gltf.nodes) for child in node.children or []}
    joints = gltf.skins[0].joints
    ends = [n for n, node in enumerate(gltf.nodes) if parents.get(n) in joints and n not in joints
            and not node.children and node.mesh is None]
    positions = np.zeros((num_keys, len(joints), 3))
    end_positions = np.zeros((num_keys, len(ends), 3))
    for frame in range(num_keys):
        cache = {}

        def world(index):
            if index not in cache:
                node = gltf.nodes[index]
                t = keyed.get((index, "translation"), [node.translation or [0, 0, 0]] * num_keys)[frame]
                r = keyed.get((index, "rotation"), [node.rotation or [0, 0, 0, 1]] * num_keys)[frame]
                s = keyed.get((index, "scale"), [node.scale or [1, 1, 1]] * num_keys)[frame]
                local = _trs(t, r, s)
                cache[index] = local if index not in parents else world(parents[index]) @ local
            return cache[index]

        for j, node in enumerate(joints):
            positions[frame, j] = world(node)[:3, 3]
        for e, node in enumerate(ends):
            end_positions[frame, e] = world(node)[:3, 3]
    return positions, end_positions


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
@pytest.mark.parametrize("case", ["biped-22-zup-mm-xyz", "quadruped-40-zup-mm-zxy", "random-33-yup-cmu-yzx"])
def test_written_file_has_the_motion_joint_positions_in_an_independent_reader(tmp_path, case, suffix):
    motion = user_case(case).motion
    path = write_gltf(motion, tmp_path / f"out{suffix}")
    expected = motion.positions() / 100.0  # metres
    if motion.up_axis == "z":
        expected = expected @ _Z_TO_Y.T
    independent = _independent_joint_positions(path)
    assert independent.shape == expected.shape
    assert np.abs(independent - expected).max() < 2e-6  # m: float32 keys
    # Our reader gives the same motion back, in cm, Y-up, with the rest offsets of the motion.
    back = read_gltf(path)
    assert (back.num_frames, back.fps, back.source_unit_cm, back.up_axis) == (motion.num_frames, motion.fps, 100.0, "y")
    assert back.skeleton.names == motion.skeleton.names
    np.testing.assert_allclose(back.positions(), expected * 100.0, atol=5e-4)
    if motion.up_axis == "y":
        np.testing.assert_allclose(back.skeleton.offsets[1:], motion.skeleton.offsets[1:], atol=1e-4)


def test_viewer_essentials_present(tmp_path):
    path = write_gltf(rig_motion(num_joints=15, num_frames=5), tmp_path / "v.glb")
    gltf = pygltflib.GLTF2.load(str(path))
    assert gltf.asset.version == "2.0" and len(gltf.skins[0].joints) == 15
    mesh_node = [n for n in gltf.nodes if n.mesh is not None][0]
    assert mesh_node.skin == 0 and gltf.meshes[0].primitives[0].mode == 1  # lines skinned to the joints
    times = _accessor(gltf, _blob(gltf), gltf.animations[0].samplers[0].input)
    np.testing.assert_allclose(times[:, 0], np.arange(5) / 120.0, atol=1e-7)
    assert gltf.accessors[gltf.animations[0].samplers[0].input].max == pytest.approx([4 / 120.0])


def _append(gltf: pygltflib.GLTF2, blob: bytearray, array: np.ndarray, kind: str) -> int:
    offset = len(blob)
    blob.extend(np.ascontiguousarray(array, dtype=np.float32).tobytes())
    gltf.bufferViews.append(pygltflib.BufferView(buffer=0, byteOffset=offset, byteLength=len(blob) - offset))
    gltf.accessors.append(pygltflib.Accessor(bufferView=len(gltf.bufferViews) - 1, componentType=5126,
                                             count=len(array), type=kind))
    return len(gltf.accessors) - 1


def test_foreign_rig_armature_static_rotations_step_and_cubic(tmp_path):
    """A file as exporters write it: an Armature node above the root, non-identity rest rotations, STEP and
    CUBICSPLINE samplers. Read positions equal the independent evaluation; the rest pose is the file's."""
    motion = rig_motion(num_joints=19, num_frames=30, fps=30.0, seed=6)
    gltf = pygltflib.GLTF2.load(str(write_gltf(motion, tmp_path / "plain.glb")))
    blob = bytearray(gltf.binary_blob())
    rng = np.random.default_rng(0)
    for node in gltf.nodes[:19]:
        node.rotation = Rotation.random(random_state=rng).as_quat().tolist()  # every joint's rotation is animated
    armature = pygltflib.Node(name="Armature", children=[0], rotation=Rotation.from_euler("X", 90, degrees=True)
                              .as_quat().tolist(), scale=[0.5, 0.5, 0.5], translation=[1.0, 0.0, 2.0])
    gltf.nodes.append(armature)
    gltf.scenes[0].nodes = [len(gltf.nodes) - 1, *gltf.scenes[0].nodes[1:]]
    animation = gltf.animations[0]
    animation.samplers[3].interpolation = "STEP"
    values = _accessor(gltf, bytes(blob), animation.samplers[5].output)
    cubic = np.stack([np.zeros_like(values), values, np.zeros_like(values)], axis=1).reshape(-1, 4)
    animation.samplers[5].output = _append(gltf, blob, cubic, "VEC4")
    animation.samplers[5].interpolation = "CUBICSPLINE"
    gltf.buffers[0].byteLength = len(blob)
    gltf.set_binary_blob(bytes(blob))
    path = tmp_path / "foreign.glb"
    gltf.save_binary(str(path))

    independent = _independent_joint_positions(path) * 100.0
    back = read_gltf(path)
    assert back.num_frames == 30 and back.fps == 30.0
    np.testing.assert_allclose(back.positions(), independent, atol=5e-4)
    # The Armature (scale 0.5) halves every bone: the rest pose is the file's, identity rotations.
    np.testing.assert_allclose(np.linalg.norm(back.skeleton.offsets[1:], axis=1),
                               0.5 * np.linalg.norm(motion.skeleton.offsets[1:], axis=1), atol=1e-4)


def test_resampling_slerps_between_keys(tmp_path):
    motion = rig_motion(num_joints=15, num_frames=20, fps=30.0, seed=2)
    path = write_gltf(motion, tmp_path / "m.glb")
    fine = read_gltf(path, fps=60.0)
    assert fine.num_frames == 39 and fine.fps == 60.0
    key_times = np.arange(20) / 30.0
    for joint in (0, 4, 11):
        slerp = Slerp(key_times, Rotation.from_quat(motion.rotations[:, joint]))
        expected = slerp(np.arange(39) / 60.0)
        angle = (expected.inv() * Rotation.from_quat(fine.rotations[:, joint])).magnitude()
        assert angle.max() < 1e-5
    np.testing.assert_allclose(fine.root_positions[1::2], (motion.root_positions[:-1] + motion.root_positions[1:]) / 2,
                               atol=1e-4)


def _broken(tmp_path, edit, name="broken.glb"):
    gltf = pygltflib.GLTF2.load(str(write_gltf(rig_motion(num_joints=15, num_frames=8), tmp_path / "base.glb",
                                                force=True)))
    edit(gltf)
    path = tmp_path / name
    gltf.save_binary(str(path))
    return path


def _add_channel(gltf, node: int, path: str, values: np.ndarray) -> None:
    """Append a LINEAR ``path`` channel on ``node`` with ``values`` (one row per key of the first sampler)."""
    blob = bytearray(gltf.binary_blob())
    animation = gltf.animations[0]
    animation.samplers.append(pygltflib.AnimationSampler(input=animation.samplers[0].input,
                                                         output=_append(gltf, blob, values, "VEC3")))
    animation.channels.append(pygltflib.AnimationChannel(
        sampler=len(animation.samplers) - 1, target=pygltflib.AnimationChannelTarget(node=node, path=path)))
    gltf.buffers[0].byteLength = len(blob)
    gltf.set_binary_blob(bytes(blob))


def _moving_translation(gltf):
    moving = np.zeros((8, 3))
    moving[:, 1] = np.linspace(0.1, 0.3, 8)
    _add_channel(gltf, 3, "translation", moving)


def _scale_track(gltf, value):
    """A scale channel on node 3 whose key 3 has ``value`` along Y."""
    scales = np.ones((8, 3))
    scales[3, 1] = value
    _add_channel(gltf, 3, "scale", scales)


def _two_roots(gltf):
    gltf.nodes[0].children = [c for c in gltf.nodes[0].children if c != 1]
    gltf.scenes[0].nodes.append(1)


@pytest.mark.parametrize(
    ("edit", "message"),
    [
        (lambda g: setattr(g, "skins", []), "has no skin"),
        (lambda g: setattr(g, "animations", []), "has no animation"),
        (_two_roots, "has 2 root joints"),
        (lambda g: _scale_track(g, 0.0), r"\('.*' scale\): key 3 \(at 0.025 s\) has scale \[1.0, 0.0, 1.0\]; a scale must "
                                          "be > 0"),
        (lambda g: _scale_track(g, -2.0), r"key 3 \(at 0.025 s\) has scale \[1.0, -2.0, 1.0\]"),
        (lambda g: _scale_track(g, np.nan), r"\('.*' scale\) output\) holds a non-finite value at item 3: "
                                             r"\[1.0, nan, 1.0\]"),
        (lambda g: setattr(g.accessors[g.animations[0].samplers[0].output], "count", 10**6), "needs bytes"),
        (lambda g: setattr(g.animations[0].samplers[0], "interpolation", "BEZIER"), "unknown interpolation 'BEZIER'"),
    ],
)
def test_bad_files_one_line(tmp_path, edit, message):
    path = _broken(tmp_path, edit)
    with pytest.raises(MotionFormatError, match=message) as error:
        read_gltf(path)
    assert str(error.value).startswith(str(path)) and "\n" not in str(error.value)


@pytest.mark.parametrize(
    ("name", "data", "message"),
    [
        ("garbage.glb", b"\x00\x01not a glb at all", "expected a binary glTF"),
        ("bad.gltf", b"{not json", "not a readable glTF 2.0 document"),
        ("v1.gltf", b'{"asset": {"version": "1.0"}}', "expected glTF version 2.x"),
        ("empty.glb", b"", "the file is empty"),
    ],
)
def test_unreadable_files_one_line(tmp_path, name, data, message):
    path = tmp_path / name
    path.write_bytes(data)
    with pytest.raises(MotionFormatError, match=message):
        read_gltf(path)


def test_truncated_glb_one_line(tmp_path):
    data = write_gltf(rig_motion(num_joints=15, num_frames=8), tmp_path / "full.glb").read_bytes()
    for cut in (12, len(data) // 2, len(data) - 3):
        path = tmp_path / f"cut{cut}.glb"
        path.write_bytes(data[:cut])
        with pytest.raises(MotionFormatError):
            read_gltf(path)


def test_cli_gltf_in_and_out(tmp_path, capsys):
    case = user_case("biped-22-zup-mm-xyz")
    source = write_gltf(case.motion, tmp_path / "in.glb")
    stream = tmp_path / "in.mcb"
    assert main(["compress", str(source), str(stream), "--codec", "quant-rot-zstd"]) == 0
    captured = capsys.readouterr()
    assert captured.err == "" and "source unit m, y up" in captured.out
    assert main(["decompress", str(stream), str(tmp_path / "out.gltf")]) == 0
    assert "m, Y-up (glTF)" in capsys.readouterr().out
    expected = case.motion.positions() @ _Z_TO_Y.T
    decoded = _independent_joint_positions(tmp_path / "out.gltf") * 100.0
    assert metrics.max_joint_error(expected, decoded) < 1.0
    # The same stream as BVH is written in metres (the glTF source unit) unless --units says otherwise.
    assert main(["decompress", str(stream), str(tmp_path / "out.bvh"), "--units", "cm"]) == 0
    assert metrics.max_joint_error(expected, read_bvh(tmp_path / "out.bvh").positions()) < 1.0
    # A BVH source compressed, decompressed to GLB: viewers get metres and Y-up.
    bvh = write_case_bvh(case, tmp_path / "mm.bvh")
    assert main(["compress", str(bvh), str(tmp_path / "b.mcb"), "--codec", "quant-rot-zstd", "--units", "mm"]) == 0
    assert main(["decompress", str(tmp_path / "b.mcb"), str(tmp_path / "b.glb")]) == 0
    assert metrics.max_joint_error(expected, _independent_joint_positions(tmp_path / "b.glb") * 100.0) < 1.0


@pytest.mark.parametrize(("num_frames", "fps"), [(142, 120.0), (4839, 120.0), (20_000, 29.97), (2, 24.0)])
def test_frame_count_and_rate_survive_float32_key_times(tmp_path, num_frames, fps):
    motion = rig_motion(num_joints=15, num_frames=num_frames, fps=fps, seed=1)
    back = read_gltf(write_gltf(motion, tmp_path / "m.glb"))
    assert back.num_frames == num_frames
    assert back.fps == pytest.approx(fps, rel=1e-6)


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
def test_a_game_rig_keeps_its_tracks_and_end_sites(tmp_path, suffix):
    """A ground root, a translated pelvis, a stretching spine and a scaled chest: the written file, evaluated by the
    independent reader, has the motion's joint and end-site positions, and our reader gives the tracks back."""
    motion = game_rig_motion(num_frames=40, stretch_cm=3.0, scale=1.4, seed=2)
    path = write_gltf(motion, tmp_path / f"game{suffix}")
    joints, ends = _independent_world_positions(path)
    assert ends.shape == (40, len(motion.skeleton.end_site_parents), 3)
    assert np.abs(joints * 100 - motion.positions()).max() < 2e-4  # cm: float32 keys in metres
    assert np.abs(ends * 100 - motion.end_site_positions()).max() < 2e-4
    back = read_gltf(path)
    np.testing.assert_array_equal(back.moving_joints(), motion.moving_joints())
    np.testing.assert_array_equal(back.scaled_joints(), motion.scaled_joints())
    np.testing.assert_array_equal(back.skeleton.end_site_parents, motion.skeleton.end_site_parents)
    assert np.abs(back.positions() - motion.positions()).max() < 1e-3
    assert np.abs(back.end_site_positions() - motion.end_site_positions()).max() < 1e-3


def test_a_moving_translation_channel_is_the_joints_translation(tmp_path):
    path = _broken(tmp_path, _moving_translation)
    back = read_gltf(path)
    np.testing.assert_array_equal(back.moving_joints(), [3])
    np.testing.assert_allclose(back.positions(), _independent_joint_positions(path) * 100, atol=5e-4)


def test_scales_on_joints_with_rest_rotations(tmp_path):
    """A uniform scale on a joint whose rest frame is turned reads as that scale; a non-uniform one along turned
    axes (a shear in the rest frame) is refused naming the joint and the frame."""
    motion = rig_motion(num_joints=15, num_frames=8, fps=30.0, seed=4)
    for uniform in (True, False):
        gltf = pygltflib.GLTF2.load(str(write_gltf(motion, tmp_path / "plain.glb", force=True)))
        gltf.nodes[3].rotation = Rotation.from_euler("xyz", [30, 40, 50], degrees=True).as_quat().tolist()
        scales = np.ones((8, 3))
        scales[2:] = [1.5, 1.5, 1.5] if uniform else [1.5, 1.0, 1.0]
        _add_channel(gltf, 3, "scale", scales)
        path = tmp_path / f"scaled{uniform}.glb"
        gltf.save_binary(str(path))
        if uniform:
            back = read_gltf(path)
            np.testing.assert_array_equal(back.scaled_joints(), [3])
            joints, ends = _independent_world_positions(path)
            np.testing.assert_allclose(back.positions(), joints * 100, atol=5e-4)
            np.testing.assert_allclose(back.end_site_positions(), ends * 100, atol=5e-4)
        else:
            with pytest.raises(MotionFormatError, match=r"joint '.*' has the non-uniform scale \[1.5, 1, 1\] at "
                                                        r"frame 2 along axes turned from its rest frame"):
                read_gltf(path)
