"""``mcb-rot`` on scaled game rigs (scale tracks, settings flag bit 13) beside ACL 2.1 at equal L∞.

    python -m mocapbench.benchmarks.mcb_rot.scales [--clips 6] [--frames 300]

The rigs are :func:`mocapbench.synthetic.game.game_rig_motion`'s (30 fps, a ground root, a translated pelvis, a
stretching spine), seeded 0.. ``--clips``, once with the chest's non-uniform squash and stretch (``scale=1.3``) and
once without it (``scale=1``, the same rotations and translations). Prints, as markdown (ratio = 12·J·F / stream
bytes over the clips pooled; L∞ over every joint of every frame): mcb-rot at ε = 0.1, 0.5, 1 cm, its L∞ and its
L∞ over the end sites, and ACL's ratio at mcb-rot's L∞ (interpolated log-log on the Pareto front of its precision
grid at shell 3 cm and 0 cm, each with and without ACL's pre-processing: ACL at its best, :func:`.rd.ratio_at`), on
both rigs.
"""

from __future__ import annotations

import argparse
import os

import numpy as np

from mocapbench.benchmarks.mcb_rot.rd import ACL_PRECISIONS_CM, rd_points, ratio_at
from mocapbench.codecs import CODECS, UNAVAILABLE, create
from mocapbench.synthetic.game import game_rig_motion

__all__ = ["main"]

EPSILONS_CM = (0.1, 0.5, 1.0)


def _end_linf(motions, eps: float) -> float:
    worst = 0.0
    for motion in motions:
        decoded = create("mcb-rot", eps_cm=eps).decode(create("mcb-rot", eps_cm=eps).encode(motion)).motion
        worst = max(worst, float(np.sqrt(np.sum((motion.end_site_positions() - decoded.end_site_positions()) ** 2,
                                                axis=-1)).max()))
    return worst


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clips", type=int, default=6)
    parser.add_argument("--frames", type=int, default=300)
    args = parser.parse_args(argv)
    print(f"load average {os.getloadavg()[0]:.2f}; {args.clips} clips x {args.frames} frames at 30 fps, 22 joints")
    print("\n| rig | ε cm | mcb-rot ratio | L∞ cm | end-site L∞ cm | ACL ratio at that L∞ | mcb-rot / ACL |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for label, scale in (("chest scaled (1.3, non-uniform)", 1.3), ("same rig unscaled", 1.0)):
        motions = [game_rig_motion(num_frames=args.frames, seed=seed, stretch_cm=4.0, scale=scale)
                   for seed in range(args.clips)]
        ours = rd_points("mcb-rot", motions, "eps_cm", EPSILONS_CM)
        acl = []
        if "acl" in CODECS:
            for shell in (3.0, 0.0):
                for pre_process in (False, True):
                    acl += rd_points("acl", motions, "precision_cm", ACL_PRECISIONS_CM, shell_cm=shell,
                                     pre_process=pre_process)
        for point in ours:
            theirs = ratio_at(acl, "linf_cm", point["linf_cm"]) if acl else float("nan")
            print(f"| {label} | {point['eps_cm']:g} | {point['ratio']:.2f} | {point['linf_cm']:.3f} | "
                  f"{_end_linf(motions, point['eps_cm']):.3f} | {theirs:.2f} | {point['ratio'] / theirs:.2f} |")
    if "acl" not in CODECS:
        print(f"\nACL unavailable: {UNAVAILABLE.get('acl', 'not registered')}")
    print(f"\nACL at its best over precision {ACL_PRECISIONS_CM} cm x shell 3 and 0 cm x pre-processing off / on.")


if __name__ == "__main__":
    main()
