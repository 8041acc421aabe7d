"""Learned codecs on the user's own skeleton from the command line: fit, compress --model, --max-error-cm."""

from __future__ import annotations

import numpy as np
import pytest

from mocapbench import metrics
from mocapbench.cli import main
from mocapbench.codecs.model_file import ModelFileError, fit_codec, load_model, save_model
from mocapbench.io import read_bvh, write_bvh
from mocapbench.ratesearch import search
from mocapbench.synthetic import sinusoidal_motion


def _small_rig(frames: int, seed: int):
    """A 9-joint rig (no model is shipped for it), random-walk joint angles."""
    from scipy.spatial.transform import Rotation

    from mocapbench.motion import Motion, Skeleton

    rng = np.random.default_rng(seed)
    joints = 9
    skeleton = Skeleton(
        names=tuple(f"j{i}" for i in range(joints)), parents=np.array([-1, 0, 1, 2, 0, 4, 5, 0, 7]),
        offsets=np.array([[0, 0, 0], [9, -5, 0], [0, -40, 2], [0, -40, 0], [-9, -5, 0], [0, -40, 2], [0, -40, 0],
                          [0, 30, 0], [0, 30, 3.0]]),  # two legs and a spine, 145 cm tall
    )
    angles = np.cumsum(rng.normal(0, 0.02, (frames, joints, 3)), axis=0)
    rotations = Rotation.from_rotvec(angles.reshape(-1, 3)).as_quat().reshape(frames, joints, 4)
    return Motion(skeleton, 60.0, np.cumsum(rng.normal(0, 0.5, (frames, 3)), axis=0) + [0, 90, 0], rotations,
                  name=f"rig{seed}")


@pytest.fixture
def rig_files(tmp_path):
    paths = []
    for seed, frames in ((1, 2), (2, 3), (3, 120)):  # two clips shorter than their 24 root-relative channels
        path = tmp_path / f"rig{seed}.bvh"
        write_bvh(_small_rig(frames, seed), path)
        paths.append(path)
    return paths


def test_fit_then_compress_and_decompress_with_the_model(tmp_path, rig_files, capsys):
    model = tmp_path / "rig.npz"
    assert main(["fit", *map(str, rig_files), "-o", str(model)]) == 0
    assert "mcb-linf model for 9 joints, fit on 3 clip(s), 125 frames" in capsys.readouterr().out
    stream = tmp_path / "a.mcb"
    assert main(["compress", str(rig_files[2]), str(stream), "--codec", "mcb-linf", "--model", str(model),
                 "--set", "eps_cm=0.5"]) == 0
    out = capsys.readouterr().out
    worst = float(out.split("L-inf ")[1].split(" cm")[0])
    assert 0 < worst <= 0.5 and "untrained" not in out
    # The stream needs the model: without it, one line saying so; with it, the bound holds.
    assert main(["decompress", str(stream), str(tmp_path / "a.npy")]) == 2
    assert "decompress --model MODEL" in capsys.readouterr().err
    assert main(["decompress", str(stream), str(tmp_path / "a.npy"), "--model", str(model)]) == 0
    decoded = np.load(tmp_path / "a.npy")
    assert metrics.max_joint_error(read_bvh(rig_files[2]).positions(), decoded) <= 0.5


def test_compress_without_a_model_says_it_ran_untrained(tmp_path, rig_files, capsys):
    assert main(["compress", str(rig_files[2]), str(tmp_path / "a.mcb"), "--codec", "mcb-linf"]) == 0
    assert "untrained (bone, bands): the model is for 31 joints, the motion has 9" in capsys.readouterr().out


def test_lsdt_without_bases_for_the_skeleton_is_one_line(tmp_path, rig_files, capsys):
    assert main(["compress", str(rig_files[2]), str(tmp_path / "a.mcb"), "--codec", "lsdt-clip"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "bases are 31 x 31 but the motion has 9 joints" in err
    model = tmp_path / "lsdt.npz"
    assert main(["fit", str(rig_files[2]), "-o", str(model), "--codec", "lsdt-clip", "--set", "sparsity=4",
                 "--set", "train_iterations=20"]) == 0
    assert main(["compress", str(rig_files[2]), str(tmp_path / "a.mcb"), "--codec", "lsdt-clip", "--model",
                 str(model), "--max-error-cm", "0.5"]) == 0
    assert "rate search" in capsys.readouterr().out


def test_fit_skips_an_unreadable_file_with_one_line(tmp_path, rig_files, capsys):
    broken = tmp_path / "broken.bvh"
    broken.write_text("HIERARCHY\nROOT\n")
    assert main(["fit", str(broken), str(rig_files[2]), "-o", str(tmp_path / "m.npz")]) == 0
    err = capsys.readouterr().err
    assert err.startswith(f"mocapbench: skipped {broken}:") and err.count("\n") == 1
    assert main(["fit", str(broken), "-o", str(tmp_path / "n.npz")]) == 2
    assert "no readable motion" in capsys.readouterr().err


def test_fit_refuses_mixed_skeletons_naming_them(tmp_path, rig_files, capsys, bvh_walk):
    assert main(["fit", str(rig_files[2]), str(bvh_walk), "-o", str(tmp_path / "m.npz")]) == 2
    assert "one skeleton, got 9 joints: rig3; 31 joints: walk" in capsys.readouterr().err


@pytest.fixture
def bvh_walk(tmp_path, synthetic_motion):
    path = tmp_path / "walk.bvh"
    write_bvh(synthetic_motion, path)
    return path


@pytest.mark.parametrize("codec, exact", [("quant-delta-zstd", True), ("quant-pred-zstd", True), ("mcb-linf", True),
                                          ("dct-spatial-clip", False),
                                          ("quant-rot-zstd", False)])
def test_max_error_cm_meets_the_bound(tmp_path, bvh_walk, capsys, codec, exact):
    stream = tmp_path / "a.mcb"
    assert main(["compress", str(bvh_walk), str(stream), "--codec", codec, "--max-error-cm", "0.8"]) == 0
    out = capsys.readouterr().out
    assert ("guaranteed" in out) == exact
    assert main(["decompress", str(stream), str(tmp_path / "a.npy")]) == 0
    assert metrics.max_joint_error(read_bvh(bvh_walk).positions(), np.load(tmp_path / "a.npy")) <= 0.8


def test_the_rate_search_takes_the_largest_step_within_the_bound(synthetic_motion):
    """Coarser than the bound's own step would break it; the search lands within 5 % of the bound's edge."""
    result = search("dct-spatial-clip", synthetic_motion, 1.0)
    assert result.met and not result.exact and result.tries > 3
    coarser = search("dct-spatial-clip", synthetic_motion, 1.0, {"step_cm": 1.0})  # the knob overrides --set
    assert coarser.settings == result.settings
    over = search("dct-spatial-clip", synthetic_motion, 1.0 / 1.2)
    assert len(over.data) > len(result.data)


def test_an_unreachable_bound_is_one_line(tmp_path, bvh_walk, capsys):
    assert main(["compress", str(bvh_walk), str(tmp_path / "a.mcb"), "--codec", "svd", "--set",
                 "factor_format=uniform", "--set", "factor_bits=2", "--max-error-cm", "0.001"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cannot reach L-inf <= 0.001 cm" in err


def test_model_files_round_trip_and_are_checked(tmp_path):
    motions = [_small_rig(40, seed) for seed in (4, 5)]
    codec = fit_codec("mcb-linf", {"eps_cm": 0.3}, motions)
    path = save_model(codec, tmp_path / "m.npz")
    loaded = load_model(path)
    assert loaded.config == codec.config and loaded.model_bytes == codec.model_bytes
    assert loaded.encode(motions[0]) == codec.encode(motions[0])
    with pytest.raises(ModelFileError, match="the model is for codec 'mcb-linf', not 'lsdt-clip'"):
        load_model(path, codec_name="lsdt-clip")
    (tmp_path / "bad.npz").write_bytes(b"not a model")
    with pytest.raises(ModelFileError, match="bad.npz: not a mocapbench model file"):
        load_model(tmp_path / "bad.npz")
    with pytest.raises(ValueError, match="learns nothing from clips"):
        fit_codec("quant-delta-zstd", {}, motions)
    with pytest.raises(ValueError, match="9 joints: rig4, rig5; 31 joints"):
        fit_codec("mcb-linf", {}, [*motions, sinusoidal_motion(num_frames=10)])


def test_compare_ranks_the_codecs_at_the_bound_and_names_the_failures(tmp_path, capsys):
    from mocapbench.experiments.compare_run import compare, format_table

    clips = [sinusoidal_motion(num_frames=80, seed=seed) for seed in (1, 2)]
    outcomes = compare(clips, 1.0, ["quant-delta-zstd", "mcb-linf", "dct-spatial-clip", "raw-zstd", "nonsense"])
    ranked = [o.codec for o in outcomes]
    assert ranked[-1] == "nonsense" and "unknown codec" in outcomes[-1].reason and "mocapbench codecs" in outcomes[-1].reason
    ratios = [o.ratio for o in outcomes if o.rows]
    assert ratios == sorted(ratios, reverse=True) and len(ratios) == 4
    for outcome in outcomes[:4]:
        assert len(outcome.rows) == 2 and all(row["max_err_cm"] <= 1.0 for row in outcome.rows)
    assert ranked.index("raw-zstd") == 3  # lossless is last of the four
    table = format_table(outcomes, 1.0)
    assert "ratio at L-inf <= 1 cm" in table and "unknown codec" in table and "480 frames" in table


@pytest.mark.slow
def test_compare_command_writes_rows_and_a_report(tmp_path, bvh_walk, capsys):
    broken = tmp_path / "broken.bvh"
    broken.write_text("HIERARCHY\n")
    runs, reports = tmp_path / "runs", tmp_path / "reports"
    assert main(["compare", str(bvh_walk), str(broken), "--codecs", "quant-delta-zstd,dct-spatial-frame", "--max-error-cm", "0.5",
                 "--runs", str(runs), "--reports", str(reports), "--name", "mine"]) == 0
    captured = capsys.readouterr()
    assert f"skipped {broken}" in captured.err
    lines = captured.out[captured.out.index("rank"):].splitlines()
    assert lines[1].split()[:2] == ["1", "quant-delta-zstd"] and lines[2].split()[:2] == ["2", "dct-spatial-frame"]
    assert len(list((runs / "mine").glob("*/results.jsonl"))) == 2  # the rows kept for a resume
    assert len(list(reports.glob("*-mine/report.md"))) == 1
