"""Write the runtime's own streams: test streams (``runtime/tests/streams/``: game rigs with translation tracks,
flags bit 10, with a still root kept apart, flags bit 12, and with scale tracks, flags bit 13, which the
repository's golden streams do not carry) and the fuzzer's small seeds
(``runtime/fuzz/seeds/``: a few joints and frames each, so that one execution costs little and a campaign reaches
millions of inputs, with every part of the format present: cuts, re-references, corrections, tracks, a still root). A
stream that names a rig of a prior (flags bit 15) is written with the prior's bytes beside it (``name.prior`` next to
``name.mcb``): the C tests open it with them, the fuzzer's seeds carry them. The C tests
(``make test``) and the fuzz campaigns read them; the Python tests compare the runtime with numpy on freshly made
streams, so these files only need to be valid.

    PYTHONPATH=. python runtime/tools/make_streams.py
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "runtime" / "tests" / "streams"


def main() -> None:
    sys.path.insert(0, str(ROOT / "tests"))
    sys.path.insert(0, str(ROOT / "tests" / "codecs" / "mcb_rot"))
    sys.path.insert(0, str(ROOT / "tests" / "fixtures" / "golden_decode"))
    from game_rig import game_rig_motion, still_root_rig
    from make_golden import spinning
    from test_mcb_rot import random_motion

    from mocapbench.codecs import create
    from mocapbench.synthetic.game import game_rig_motion as synthetic_game_rig

    OUT.mkdir(parents=True, exist_ok=True)
    cases = {
        "game-rig-tracks.mcb": (game_rig_motion(90, seed=3), dict(eps_cm=0.5, segment_frames=32, chunk_frames=32)),
        "game-rig-stretch.mcb": (synthetic_game_rig(num_frames=150, seed=4, stretch_cm=8.0), dict(eps_cm=0.2)),
        "game-rig-still-root.mcb": (still_root_rig(100, seed=6, position=(2.5, 0.0, -4.0)),
                                    dict(eps_cm=0.3, segment_frames=32, chunk_frames=64)),
        "game-rig-still-root-stretch.mcb": (_still(synthetic_game_rig(num_frames=70, seed=7, stretch_cm=8.0)),
                                            dict(eps_cm=0.5)),
        "game-rig-scales.mcb": (game_rig_motion(40, seed=9, scaled=True), dict(eps_cm=0.5)),
    }
    for name, (motion, settings) in cases.items():
        (OUT / name).write_bytes(create("mcb-rot", **settings).encode(motion))
        print(OUT / name)
    _write_prior(OUT / "game-rig-prior.mcb", [still_root_rig(30, seed=1), game_rig_motion(30, seed=2)],
                 still_root_rig(150, seed=12, position=(0.0, 0.0, 0.0)), dict(eps_cm=0.5, chunk_frames=64))
    seeds = ROOT / "runtime" / "fuzz" / "seeds"
    seeds.mkdir(parents=True, exist_ok=True)
    small = {
        "rigid-4j-40f.mcb": (random_motion(1, 4, 40, 0.3, 0.3), dict(eps_cm=0.05, segment_frames=16, chunk_frames=16)),
        "rigid-6j-24f-shell.mcb": (random_motion(2, 6, 24, 0.0, 0.02), dict(eps_cm=0.5, shell_cm=2.0,
                                                                           segment_frames=7, chunk_frames=20)),
        "spin-8j-60f.mcb": (spinning(random_motion(3, 8, 60, 0.0, 0.3)), dict(eps_cm=0.1, segment_frames=32,
                                                                             chunk_frames=32)),
        "rigid-1j-9f.mcb": (random_motion(4, 1, 9, 0.0, 0.3), dict(eps_cm=2.0, segment_frames=4, chunk_frames=4)),
        "game-rig-12f.mcb": (game_rig_motion(12, seed=5), dict(eps_cm=1.0, segment_frames=8, chunk_frames=8)),
        "still-root-10f.mcb": (still_root_rig(10, seed=8, position=(1.0, 0.0, 2.0)),
                               dict(eps_cm=1.0, segment_frames=4, chunk_frames=8)),
        "scales-12f.mcb": (game_rig_motion(12, seed=10, scaled=True),
                           dict(eps_cm=1.0, segment_frames=8, chunk_frames=8)),
    }
    for name, (motion, settings) in small.items():
        (seeds / name).write_bytes(create("mcb-rot", **settings).encode(motion))
        print(seeds / name, (seeds / name).stat().st_size, "bytes")
    _write_prior(seeds / "prior-3j-10f.mcb", [random_motion(11, 3, 12, 0.0, 0.3), random_motion(12, 2, 12, 0.0, 0.3)],
                 random_motion(11, 3, 10, 0.0, 0.3), dict(eps_cm=1.0, segment_frames=4, chunk_frames=8))
    _write_prior(seeds / "prior-still-root-9f.mcb", [still_root_rig(12, seed=13)], still_root_rig(9, seed=13),
                 dict(eps_cm=1.0, segment_frames=4, chunk_frames=8))


def _write_prior(path: Path, training, motion, settings) -> None:
    """A stream of ``motion`` naming its rig in a prior fit on ``training`` (which holds that rig), and the prior's
    bytes beside it (``.prior``)."""
    from mocapbench.codecs import container, create
    from mocapbench.codecs.mcb_rot import stream

    codec = create("mcb-rot", **settings).fit(training)
    data = codec.encode(motion)
    header, payload = container.unpack(data, "mcb-rot")
    assert stream.read_info(header, payload, codec._prior).settings.prior, "the prior does not hold the clip's rig"
    path.write_bytes(data)
    path.with_suffix(".prior").write_bytes(codec._prior.data)
    print(path, len(data), "bytes, prior", len(codec._prior.data), "bytes")


def _still(motion):
    """``motion`` with its ground root held still (the identity rotation, at the origin): a still root kept apart,
    its child (joint 1) carrying the trajectory."""
    import numpy as np

    from mocapbench.motion import Motion

    rotations = motion.rotations.copy()
    rotations[:, 0] = (0.0, 0.0, 0.0, 1.0)
    return Motion(motion.skeleton, motion.fps, np.zeros_like(motion.root_positions), rotations, name="still",
                  translations=motion.translations)


if __name__ == "__main__":
    main()
