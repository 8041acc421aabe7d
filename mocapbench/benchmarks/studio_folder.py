"""A studio's folder of BVH files, generated: what ``mocapbench compare`` is measured on when no real one is at hand.

    python -m mocapbench.benchmarks.studio_folder OUT/            # writes OUT/*.bvh (+ sidecars), prints a table
    python -m mocapbench.benchmarks.studio_folder OUT/ --fps 30   # every clip at 30 fps (the speed target's folder)

Nine clips, as a game studio's engineer might hand over: skeletons of 19 to 60 joints; several clips of one
skeleton (three walks of a 31-joint biped, two of a 52-joint one) and one clip of each other skeleton; files in cm,
in inches (two with a ``FILE.units`` sidecar saying so, one without: a 64 cm "person" with an adult's proportions)
and in CMU units (no sidecar: a 28 cm body); a rig whose rest pose stands along Y but whose root turns it to stand
along Z in every frame; a Z-up rig; 30 and 120 fps. Each clip is about 500 frames. The motions are the seeded
sinusoids of :mod:`mocapbench.synthetic` (not motion capture: they exercise the reading, checking and ranking, not
the codecs' real-world ratios).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from mocapbench.io.bvh import write_bvh
from mocapbench.io.unit_choice import sidecar_path
from mocapbench.io.units import UNITS_CM, unit_label
from mocapbench.motion import Motion
from mocapbench.synthetic import rig_motion

__all__ = ["CLIPS", "StudioClip", "turned_by_the_root", "write_folder", "main"]


@dataclasses.dataclass(frozen=True)
class StudioClip:
    """One file of the folder: the rig, its unit, its axes and whether a sidecar states the unit."""

    name: str
    num_joints: int
    unit: str
    fps: float
    seed: int
    axes: str = "y-up"  # "y-up", "z-up" (turned as a whole) or "turned-by-root" (rest pose Y, frames Z)
    sidecar: bool = False
    speed_cm_s: float = 120.0


CLIPS = (
    StudioClip("hero_walk_a", 31, "cm", 30.0, 1),
    StudioClip("hero_walk_b", 31, "cm", 30.0, 2),
    StudioClip("hero_walk_c", 31, "cm", 30.0, 3),
    StudioClip("mocap_inch_a", 52, "inch", 30.0, 4, sidecar=True),
    StudioClip("mocap_inch_b", 52, "inch", 30.0, 5, sidecar=True),
    StudioClip("legacy_inch", 24, "inch", 30.0, 6),
    StudioClip("cmu_units", 19, "cmu", 30.0, 7),
    StudioClip("idle_turned_by_root", 40, "cm", 120.0, 8, axes="turned-by-root", speed_cm_s=0.0),
    StudioClip("fingers_zup", 60, "cm", 120.0, 9, axes="z-up"),
)


def turned_by_the_root(motion: Motion) -> Motion:
    """``motion`` with its root turned +90 degrees about X on every frame: the rest pose stands along Y, the frames
    along Z (what an exporter that bakes the axis change into the root writes)."""
    turn = Rotation.from_euler("X", 90, degrees=True)
    rotations = np.array(motion.rotations)
    rotations[:, 0] = (turn * Rotation.from_quat(rotations[:, 0])).as_quat()
    return dataclasses.replace(motion, rotations=rotations, root_positions=turn.apply(np.array(motion.root_positions)),
                               up_axis="z")


def clip_motion(clip: StudioClip, num_frames: int, fps: float | None = None) -> Motion:
    """The motion (cm) of one clip."""
    motion = rig_motion(num_joints=clip.num_joints, unit=clip.unit, fps=fps or clip.fps, num_frames=num_frames,
                        seed=clip.seed, up_axis="z" if clip.axes == "z-up" else "y", speed_cm_s=clip.speed_cm_s)
    return turned_by_the_root(motion) if clip.axes == "turned-by-root" else motion


def write_folder(folder: str | Path, *, num_frames: int = 500, fps: float | None = None,
                 force: bool = False) -> list[Path]:
    """Write every clip of :data:`CLIPS` into ``folder`` (created), in its unit, with its sidecar; returns the files."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for clip in CLIPS:
        path = write_bvh(clip_motion(clip, num_frames, fps), folder / f"{clip.name}.bvh",
                         length_unit_cm=UNITS_CM[clip.unit], overwrite=force)
        if clip.sidecar:
            sidecar_path(path).write_text(f"units: {clip.unit}\n")
        written.append(path)
    return written


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", help="folder to write the clips into")
    parser.add_argument("--frames", type=int, default=500, help="frames per clip (default 500)")
    parser.add_argument("--fps", type=float, help="every clip at this rate (default: 30 or 120 per clip)")
    parser.add_argument("--force", action="store_true", help="overwrite existing files")
    args = parser.parse_args(argv)
    try:
        files = write_folder(args.folder, num_frames=args.frames, fps=args.fps, force=args.force)
    except (OSError, ValueError) as error:
        print(f"studio_folder: error: {error}", file=sys.stderr)
        return 2
    print(f"{'file':<28} {'joints':>6} {'fps':>5}  {'unit':<16} {'sidecar':<8} axes")
    for clip, path in zip(CLIPS, files):
        print(f"{path.name:<28} {clip.num_joints:>6} {args.fps or clip.fps:>5g}  {unit_label(UNITS_CM[clip.unit]):<16} "
              f"{'yes' if clip.sidecar else 'no':<8} {clip.axes}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
