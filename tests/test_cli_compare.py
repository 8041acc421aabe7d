"""``mocapbench compare`` as a studio runs it: what it read, models held out, rows kept, Ctrl-C, resume, traps."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from mocapbench.benchmarks.studio_folder import clip_motion, CLIPS, turned_by_the_root
from mocapbench.cli import main
from mocapbench.io.bvh import write_bvh
from mocapbench.io.unit_choice import sidecar_path
from mocapbench.synthetic import rig_motion

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture
def studio(tmp_path):
    """Four short clips: two of one skeleton, one in inches (no sidecar), one turned Z-up by its root (in a subfolder)."""
    folder = tmp_path / "studio"
    (folder / "takes").mkdir(parents=True)
    for seed in (1, 2):
        write_bvh(rig_motion(num_joints=20, num_frames=40, fps=30.0, seed=seed), folder / f"walk_{seed}.bvh")
    write_bvh(rig_motion(num_joints=24, num_frames=40, fps=30.0, seed=3), folder / "legacy.bvh", length_unit_cm=2.54)
    turned = turned_by_the_root(rig_motion(num_joints=16, num_frames=40, fps=30.0, seed=4, speed_cm_s=0.0))
    write_bvh(turned, folder / "takes" / "idle.bvh")
    return folder


def _run(argv, capsys):
    code = main(argv)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_compare_says_what_it_read_and_how_each_model_was_obtained(tmp_path, studio, capsys):
    code, out, err = _run(["compare", str(studio), "--codecs", "mcb-linf,quant-delta-zstd", "--no-report",
                           "--runs", str(tmp_path / "runs")], capsys)
    assert code == 0, err
    # Every file, the subfolder's too, with its unit, axis and verdict.
    assert "legacy.bvh: cm (default; --units to change)" in out and "pass --units inch" in out
    assert "idle.bvh" in out and "z up (detected: the root-to-" in out
    assert "walk_1.bvh: cm (default; --units to change), y up" in out
    table = out[out.index("rank"):]
    assert "out-of-sample" in table and " B" in table and "with models" in table
    assert "Models held out" in out
    assert "wall" in out and "CPU" in out
    # Progress per clip on stderr, with what is left (the two codecs run side by side: their lines interleave).
    assert "[1/8] " in err and "] mcb-linf on" in err and "] quant-delta-zstd on" in err and "left" in err


def test_units_per_file_and_strict(tmp_path, studio, capsys):
    code, out, err = _run(["compare", str(studio), "--codecs", "raw-zstd", "--no-report", "--units",
                           "legacy.bvh:inch", "--runs", str(tmp_path / "runs")], capsys)
    assert code == 0 and "legacy.bvh: inch (--units legacy.bvh:inch)" in out and "pass --units" not in out
    code, out, err = _run(["compare", str(studio), "--codecs", "raw-zstd", "--no-report", "--strict",
                           "--runs", str(tmp_path / "runs")], capsys)
    assert code == 2 and "legacy.bvh" in err and "(--strict)" in err and err.count("\n") == 1
    sidecar_path(studio / "legacy.bvh").write_text("units: inch\n")
    code, out, err = _run(["compare", str(studio), "--codecs", "raw-zstd", "--no-report", "--strict",
                           "--runs", str(tmp_path / "runs")], capsys)
    assert code == 0 and "legacy.bvh: inch (sidecar legacy.bvh.units)" in out
    code, out, err = _run(["compare", str(studio), "--codecs", "raw-zstd", "--no-report", "--units", "typo.bvh:m",
                           "--runs", str(tmp_path / "runs")], capsys)
    assert code == 2 and "typo.bvh" in err


def test_no_recurse_stays_in_the_folder(tmp_path, studio, capsys):
    code, out, _ = _run(["compare", str(studio), "--codecs", "raw-zstd", "--no-report", "--no-recurse",
                         "--runs", str(tmp_path / "runs")], capsys)
    assert code == 0 and "idle.bvh" not in out


def test_in_sample_models_are_paid_for(tmp_path, studio, capsys):
    code, out, _ = _run(["compare", str(studio), "--codecs", "mcb-linf", "--no-report", "--in-sample",
                         "--units", "legacy.bvh:inch", "--runs", str(tmp_path / "runs")], capsys)
    assert code == 0 and "(models in)" in out and "in-sample" in out


def test_a_second_run_resumes(tmp_path, studio, capsys):
    argv = ["compare", str(studio), "--codecs", "quant-delta-zstd", "--no-report", "--units", "legacy.bvh:inch",
            "--runs", str(tmp_path / "runs")]
    assert _run(argv, capsys)[0] == 0
    code, out, err = _run(argv, capsys)
    assert code == 0 and "4 clip row(s) kept from an earlier run" in out and "kept from the last run" in err


@pytest.mark.parametrize("workers", ["1", "2"])
def test_ctrl_c_prints_what_finished_keeps_the_rows_and_the_next_run_resumes(tmp_path, studio, workers):
    runs = tmp_path / "runs"
    env = {**os.environ, "PYTHONPATH": str(REPO), "PYTHONUNBUFFERED": "1"}
    argv = [sys.executable, "-m", "mocapbench", "compare", str(studio), "--codecs",
            "raw-zstd,quant-delta-zstd,svd,dct-spatial-clip,pga-ik", "--no-report", "--units", "legacy.bvh:inch",
            "--runs", str(runs), "--workers", workers]
    # A child started from a background job inherits SIGINT ignored, and Python then installs no handler: restore it.
    process = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    # One worker runs the codecs in the order given: once quant-delta-zstd has a row, raw-zstd has finished and three
    # codecs are left. Two run the longest first, so raw-zstd and quant-delta-zstd come last, and waiting for their
    # rows raced the run's end on a loaded machine (exit 0 before the interrupt came): there the interrupt comes at
    # the first whole row of any codec, with the others still to run.
    waited = (runs / "compare" / "quant-delta-zstd" / "results.jsonl",) if workers == "1" else ()
    deadline, first = time.monotonic() + 240, None
    while time.monotonic() < deadline and first is None:
        found = [path for path in waited if path.exists()] if waited else list(runs.glob("compare/*/results.jsonl"))
        first = next((path for path in found if path.read_text().endswith("\n")), None)
        time.sleep(0.01)
    assert first is not None, "no codec wrote a row within 240 s"
    process.send_signal(signal.SIGINT)
    out, err = process.communicate(timeout=120)
    assert process.returncode == 130, err
    assert "Traceback" not in err and "interrupted:" in err and "run the same command again to resume" in err
    if workers == "1":
        assert "raw-zstd" in out  # the table of what finished
    else:  # the longest codecs start first, side by side: which had finished depends on the machine's speed
        assert "codec(s) finished" in err
    again = subprocess.run(argv[:6] + ["raw-zstd,quant-delta-zstd" if workers == "1" else first.parent.name]
                           + argv[7:], capture_output=True, text=True, env=env, timeout=240)
    assert again.returncode == 0 and "kept from an earlier run" in again.stdout


@pytest.mark.parametrize("suffix", [".bvh", ".glb", ".fbx"])
def test_compress_refuses_an_output_named_like_a_motion_file(tmp_path, studio, capsys, suffix):
    out = tmp_path / f"out{suffix}"
    code, _, err = _run(["compress", str(studio / "walk_1.bvh"), str(out), "--codec", "raw-zstd"], capsys)
    assert code == 2 and not out.exists()
    assert f"compress writes a bitstream, not a {suffix} motion file; name the output out.mcb" in err


def test_compress_states_the_model_a_decoder_needs_and_inspect_names_it(tmp_path, capsys):
    source = tmp_path / "cmu_like.bvh"
    write_bvh(rig_motion(num_joints=31, num_frames=60, seed=5), source)
    stream = tmp_path / "s.mcb"
    code, out, _ = _run(["compress", str(source), str(stream), "--codec", "lsdt-frame"], capsys)
    assert code == 0 and "the decoder also needs the model shipped with the package: 23,064 bytes" in out
    assert ":1 with them" in out
    code, out, _ = _run(["inspect", str(stream)], capsys)
    assert code == 0 and "model needed" in out and "the committed LSDT bases shipped with the package" in out
    fixed = tmp_path / "f.mcb"
    assert _run(["compress", str(source), str(fixed), "--codec", "dct-spatial-frame"], capsys)[0] == 0
    assert "none (a fixed DCT transform)" in _run(["inspect", str(fixed)], capsys)[1]


def test_codecs_lists_types_outputs_and_models(capsys):
    code, out, _ = _run(["codecs"], capsys)
    assert code == 0 and "None" not in out
    assert "rdo (bool, default True, true or false)" in out and "eps_cm (float, default 1.0, in [0.001, 100] cm)" in out
    lsdt = out[out.index("lsdt-frame:"):]
    assert "outputs joint positions only" in lsdt.splitlines()[1] and "`mocapbench fit --codec lsdt-frame`" in lsdt
    assert "outputs rotations (BVH/glTF); needs no model" in out[out.index("svd:"):]


def test_messages_name_commands_not_python_calls(tmp_path, studio, capsys):
    code, _, err = _run(["compress", str(studio / "walk_1.bvh"), str(tmp_path / "x.mcb"), "--codec", "lsdt-frame",
                         "--set", "basis=fit"], capsys)
    assert code == 2 and "`mocapbench fit" in err and "fit(motions)" not in err


def test_a_benchmark_without_the_cmu_folder_says_so_in_one_line(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(REPO), "MOCAPBENCH_CMU_DIR": str(tmp_path / "nowhere")}
    result = subprocess.run([sys.executable, "-m", "mocapbench.benchmarks.io"], capture_output=True, text=True,
                            env=env, cwd=tmp_path, timeout=120)
    assert result.returncode == 2 and "Traceback" not in result.stderr
    assert result.stderr.count("\n") == 1 and "CMU data folder" in result.stderr
