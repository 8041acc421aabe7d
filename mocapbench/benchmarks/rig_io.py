"""Game rigs through the file formats: round trips judged by second readers, and what each reader costs.

``python -m mocapbench.benchmarks.rig_io roundtrip [--bandai-dir D] [--cmu-dir D] [--limit N]``
    Reads every Bandai Namco BVH file (and the CMU BVH clips), writes each back as BVH and as GLB, and prints per
    source and format the worst joint and end-site world-position difference (cm) between the source motion and
    the written file as a *second reader* evaluates it:

    * BVH: :func:`~mocapbench.io.bvh.read_bvh` reads the file back, and :func:`independent_positions` (4x4 matrices
      joint by joint, not :meth:`Motion.positions <mocapbench.motion.Motion.positions>`) evaluates it;
    * GLB: :func:`gltf_positions` evaluates the file with ``pygltflib``'s parse and its own matrix maths (T R S
      node by node), no mocapbench reader involved;

    * FBX: mocapbench has no product FBX writer; the file is the ASCII FBX 7.4 of :mod:`mocapbench.io.fbx_ascii`
      (joints only, no end sites), read back by ufbx through :func:`~mocapbench.io.fbx.read_fbx` and evaluated by
      :func:`independent_positions`;

    against the source's :meth:`Motion.positions` and :meth:`Motion.end_site_positions`. The target is 1e-3 cm.

``python -m mocapbench.benchmarks.rig_io cost [--frames F] [--repeats R]``
    The CPU and wall time per frame and joint of each reader (BVH, GLB, FBX) on the same synthetic game rig
    written in each format (FBX: the ASCII FBX 7.4 a fixture writer makes), median of ``R`` runs after a warm-up,
    and each reader's cost relative to the BVH reader's (the FBX target: within 3x).
"""

from __future__ import annotations

import argparse
import platform
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from mocapbench.io.bvh import read_bvh, write_bvh
from mocapbench.io.fbx import read_fbx
from mocapbench.io.fbx_ascii import write_fbx_ascii
from mocapbench.io.gltf import write_gltf
from mocapbench.metrics.timing import METHOD, load_average, measure
from mocapbench.motion import Motion

__all__ = ["independent_positions", "gltf_positions", "roundtrip_rows", "cost_rows", "TARGET_CM"]

#: The round-trip target: joint and end-site world positions within this many cm of the source.
TARGET_CM = 1e-3


def independent_positions(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """Joint (F, J, 3) and end-site (F, E, 3) world positions, cm, by 4x4 matrices joint by joint (local = T R S).

    A second forward kinematics, written apart from :meth:`Motion.positions` (which goes by tree depth in a
    component-major layout), vectorized over frames only.
    """
    skeleton = motion.skeleton
    num_frames = motion.num_frames
    translations = motion.local_translations()
    scales = np.ones((num_frames, motion.num_joints, 3)) if motion.scales is None else motion.scales
    world = np.zeros((motion.num_joints, num_frames, 4, 4))
    for j in range(motion.num_joints):
        local = np.zeros((num_frames, 4, 4))
        local[:, :3, :3] = Rotation.from_quat(motion.rotations[:, j]).as_matrix() * scales[:, j, None, :]
        local[:, :3, 3] = translations[:, j]
        local[:, 3, 3] = 1.0
        parent = skeleton.parents[j]
        world[j] = local if parent < 0 else world[parent] @ local
    ends = np.einsum("efab,eb->fea", world[skeleton.end_site_parents],
                     np.concatenate([skeleton.end_site_offsets, np.ones((len(skeleton.end_site_parents), 1))], axis=1))
    return world[:, :, :3, 3].transpose(1, 0, 2), ends[..., :3]


def _accessor(gltf, blob: bytes, index: int) -> np.ndarray:
    """A float32/uint16 accessor of a GLB as (count, width) float64 (what the writer emits)."""
    accessor = gltf.accessors[index]
    view = gltf.bufferViews[accessor.bufferView]
    dtype = {5126: np.float32, 5123: np.uint16, 5125: np.uint32}[accessor.componentType]
    width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}[accessor.type]
    start = (view.byteOffset or 0) + (accessor.byteOffset or 0)
    return np.frombuffer(blob, dtype=dtype, count=accessor.count * width, offset=start).reshape(-1, width).astype(float)


def gltf_positions(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """World positions, cm, at every key of a GLB's skin joints (F, J, 3) and end sites (F, E, 3).

    Parsed by ``pygltflib`` and evaluated node by node with 4x4 matrices (T R S, glTF 2.0 section 5.25) from the
    keyed values (one key per frame, as :func:`~mocapbench.io.gltf.write_gltf` writes); end sites are the childless
    non-joint nodes without a mesh under a joint, in node order. Metres are turned into cm.
    """
    import pygltflib

    gltf = pygltflib.GLTF2.load(str(path))
    blob = gltf.binary_blob()
    animation = gltf.animations[0]
    keyed = {}
    for channel in animation.channels:
        keyed[(channel.target.node, channel.target.path)] = _accessor(gltf, blob, animation.samplers[channel.sampler]
                                                                      .output)
    num_keys = len(next(iter(keyed.values())))
    parents = {child: index for index, node in enumerate(gltf.nodes) for child in node.children or []}
    joints = list(gltf.skins[0].joints)
    ends = [n for n, node in enumerate(gltf.nodes)
            if parents.get(n) in joints and n not in joints and not node.children and node.mesh is None]
    world: dict[int, np.ndarray] = {}

    def evaluate(index: int) -> np.ndarray:
        if index not in world:
            node = gltf.nodes[index]
            t = keyed.get((index, "translation"), np.tile(node.translation or [0.0, 0.0, 0.0], (num_keys, 1)))
            r = keyed.get((index, "rotation"), np.tile(node.rotation or [0.0, 0.0, 0.0, 1.0], (num_keys, 1)))
            s = keyed.get((index, "scale"), np.tile(node.scale or [1.0, 1.0, 1.0], (num_keys, 1)))
            local = np.zeros((num_keys, 4, 4))
            local[:, :3, :3] = Rotation.from_quat(r).as_matrix() * s[:, None, :]
            local[:, :3, 3] = t
            local[:, 3, 3] = 1.0
            world[index] = local if index not in parents else evaluate(parents[index]) @ local
        return world[index]

    joint_positions = np.stack([evaluate(node)[:, :3, 3] for node in joints], axis=1) * 100.0
    end_positions = np.stack([evaluate(node)[:, :3, 3] for node in ends], axis=1) * 100.0 if ends else \
        np.zeros((num_keys, 0, 3))
    return joint_positions, end_positions


def _worst(expected: tuple[np.ndarray, np.ndarray], got: tuple[np.ndarray, np.ndarray]) -> tuple[float, float]:
    """Largest joint and end-site distance (cm) between two (joints, end sites) pairs; inf when shapes differ."""
    out = []
    for a, b in zip(expected, got):
        out.append(float(np.linalg.norm(a - b, axis=-1).max()) if a.shape == b.shape and a.size else
                   (0.0 if a.shape == b.shape else float("inf")))
    return out[0], out[1]


def roundtrip_rows(sources: list[tuple[str, Motion]], folder: Path) -> list[dict]:
    """One row per source motion: frames, joints, moving joints and the worst difference per format (cm)."""
    rows = []
    for label, motion in sources:
        expected = (motion.positions(), motion.end_site_positions())
        if motion.up_axis != "y":
            raise ValueError(f"{label}: the round trip compares Y-up motions (GLB turns a {motion.up_axis}-up one)")
        bvh = write_bvh(motion, folder / "roundtrip.bvh", length_unit_cm=motion.source_unit_cm, overwrite=True)
        back = read_bvh(bvh, length_unit_cm=motion.source_unit_cm)
        glb = write_gltf(motion, folder / "roundtrip.glb", force=True)
        fbx = read_fbx(write_fbx_ascii(motion, folder / "roundtrip.fbx", unit_cm=motion.source_unit_cm,
                                       overwrite=True))
        rows.append({
            "source": label,
            "name": motion.name,
            "frames": motion.num_frames,
            "joints": motion.num_joints,
            "end_sites": len(motion.skeleton.end_site_parents),
            "moving": len(motion.moving_joints()),
            "bvh": _worst(expected, independent_positions(back)),
            "glb": _worst(expected, gltf_positions(glb)),
            "fbx": (_worst(expected, independent_positions(fbx))[0], float("nan")),
        })
    return rows


def format_roundtrip(rows: list[dict]) -> str:
    """Markdown: per source and format, files, frames, worst joint and end-site difference, files within target."""
    lines = [
        "| source | format | files | frames | joints (moving) | worst joint cm | worst end site cm | files within "
        f"{TARGET_CM:g} cm |",
        "|---|---|---:|---:|---|---:|---:|---:|",
    ]
    for source in sorted({row["source"] for row in rows}):
        mine = [row for row in rows if row["source"] == source]
        joints = sorted({f"{row['joints']} ({row['moving']})" for row in mine})
        for fmt, second in (("bvh", "BVH (read_bvh + independent FK)"), ("glb", "GLB (pygltflib + own matrices)"),
                            ("fbx", "FBX, ASCII, joints only (read_fbx + independent FK)")):
            worst = [row[fmt] for row in mine]
            within = sum(np.nanmax(w) <= TARGET_CM for w in worst)
            lines.append(
                f"| {source} | {second} | {len(mine)} | {sum(row['frames'] for row in mine):,} | {', '.join(joints)} | "
                f"{max(w[0] for w in worst):.2e} | {_cm(max(w[1] for w in worst))} | {within}/{len(mine)} |"
            )
    return "\n".join(lines)


def _cm(value: float) -> str:
    """A distance for the table; NaN (a format that does not carry end sites) as "not written"."""
    return "not written" if np.isnan(value) else f"{value:.2e}"


def _sources(bandai_dir: str | None, cmu_dir: str | None, limit: int | None) -> list[tuple[str, Motion]]:
    """(source label, motion) of every Bandai Namco file and every CMU BVH clip found (``limit`` of each)."""
    from mocapbench.datasets.bandai import clip_files
    from mocapbench.datasets.cmu import ALL_SPLIT, CMU_CM_PER_UNIT, DataNotFoundError, clip_names, cmu_data_dir

    sources = []
    try:
        for _, _, path in clip_files("bandai_all", bandai_dir)[:limit]:
            sources.append(("bandai (BVH, cm)", read_bvh(path)))
    except DataNotFoundError as error:
        print(f"skipping the Bandai Namco files: {error}", file=sys.stderr)
    try:
        root = cmu_data_dir(cmu_dir)
        for name in clip_names(ALL_SPLIT, data_dir=root)[:limit]:
            motion = read_bvh(root / "bvh" / f"{name}.bvh", length_unit_cm=CMU_CM_PER_UNIT, drop_first_frame=True)
            sources.append(("CMU (BVH, CMU units)", Motion(motion.skeleton, motion.fps, motion.root_positions,
                                                           motion.rotations, motion.name,
                                                           source_unit_cm=CMU_CM_PER_UNIT)))
    except DataNotFoundError as error:
        print(f"skipping the CMU clips: {error}", file=sys.stderr)
    return sources


def cost_rows(num_frames: int, repeats: int, folder: Path) -> list[dict]:
    """CPU and wall microseconds per frame and joint of each reader on one synthetic game rig of ``num_frames``."""
    from mocapbench.io.gltf import read_gltf
    from mocapbench.synthetic.game import game_rig_motion

    motion = game_rig_motion(num_frames=num_frames, fps=30.0, stretch_cm=2.0, seed=0)
    files = {
        "BVH": (write_bvh(motion, folder / "cost.bvh", overwrite=True), read_bvh),
        "GLB": (write_gltf(motion, folder / "cost.glb", force=True), read_gltf),
        "FBX (ASCII)": (write_fbx_ascii(motion, folder / "cost.fbx", overwrite=True), read_fbx),
    }
    rows = []
    for fmt, (path, reader) in files.items():
        timing, read = measure(lambda reader=reader, path=path: reader(path), repeats=repeats, warmup=1)
        cells = read.num_frames * read.num_joints
        rows.append({"format": fmt, "frames": read.num_frames, "joints": read.num_joints,
                     "bytes": path.stat().st_size, "cpu_s": timing.cpu_s, "wall_s": timing.wall_s,
                     "cpu_us": timing.cpu_s / cells * 1e6, "wall_us": timing.wall_s / cells * 1e6})
    for row in rows:
        row["vs_bvh"] = row["cpu_us"] / rows[0]["cpu_us"]
    return rows


def format_cost(rows: list[dict]) -> str:
    """Markdown table of :func:`cost_rows`."""
    lines = ["| reader | frames x joints | file bytes | CPU s | wall s | CPU us per frame.joint | wall us per frame.joint "
             "| CPU vs BVH |", "|---|---|---:|---:|---:|---:|---:|---:|"]
    for row in rows:
        lines.append(f"| {row['format']} | {row['frames']:,} x {row['joints']} | {row['bytes']:,} | {row['cpu_s']:.3f} | "
                     f"{row['wall_s']:.3f} | {row['cpu_us']:.3f} | {row['wall_us']:.3f} | {row['vs_bvh']:.2f}x |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m mocapbench.benchmarks.rig_io", description=__doc__.split("\n")[0])
    commands = parser.add_subparsers(dest="command", required=True)
    roundtrip = commands.add_parser("roundtrip", help="round trips of the Bandai Namco and CMU files: BVH, GLB, FBX")
    roundtrip.add_argument("--bandai-dir", default=None, help="Bandai Namco folder (see mocapbench.datasets.bandai)")
    roundtrip.add_argument("--cmu-dir", default=None, help="CMU folder (see mocapbench.datasets.cmu)")
    roundtrip.add_argument("--limit", type=int, default=None, help="at most this many files of each data set")
    cost = commands.add_parser("cost", help="each reader's time per frame and joint on one synthetic game rig")
    cost.add_argument("--frames", type=int, default=20_000, help="frames of the rig (22 joints), default 20000")
    cost.add_argument("--repeats", type=int, default=3, help="timed runs per reader (median), default 3")
    args = parser.parse_args(argv)
    before = load_average()
    with tempfile.TemporaryDirectory() as folder:
        if args.command == "roundtrip":
            rows = roundtrip_rows(_sources(args.bandai_dir, args.cmu_dir, args.limit), Path(folder))
            print(format_roundtrip(rows))
            for fmt in ("bvh", "glb", "fbx"):
                worst = max(rows, key=lambda row, fmt=fmt: np.nanmax(row[fmt]), default=None)
                if worst:
                    print(f"Worst {fmt.upper()} file: {worst['name']} ({worst['source']}), "
                          f"{np.nanmax(worst[fmt]):.2e} cm.")
        else:
            print(format_cost(cost_rows(args.frames, args.repeats, Path(folder))))
            print(f"\n{METHOD.format(repeats=args.repeats, warmup=1, threads=1)}.")
    machine = platform.processor() or platform.machine()
    print(f"Load average {before:.2f} before, {load_average():.2f} after; {machine}, Python "
          f"{platform.python_version()}.")
    return 0


if __name__ == "__main__":
    sys.exit(main())
