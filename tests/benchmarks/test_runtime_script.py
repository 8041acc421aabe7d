"""The runtime benchmark (``python -m mocapbench.benchmarks.runtime`` and its C++ harness): ``--set`` checked before
anything is built or encoded, both decoders built for the same instruction set, the whole pose the harness times equal to Python's decode (mcb-rot and ACL, on a game
rig), a bad manifest, a missing data folder or a ``--keep`` folder it would overwrite one line and a non-zero exit,
never a traceback."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from mocapbench.benchmarks import runtime

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def assert_refused_before_building(monkeypatch, capsys, argv: list[str], message: str) -> None:
    """``main(argv)`` exits 2 with ``message`` in its one usage line, no traceback, and builds no harness."""
    monkeypatch.setattr(runtime, "build_harness", lambda *_: pytest.fail(f"built before {argv} was refused"))
    with pytest.raises(SystemExit) as exit_info:
        runtime.main(argv)
    assert exit_info.value.code == 2
    error = capsys.readouterr().err.strip().splitlines()
    assert message in error[-1] and "Traceback" not in "\n".join(error)


@pytest.mark.parametrize("pair, message", [
    ("segment_frames", "expects key=value"),
    ("no_such_field=3", "Unknown parameter"),
    ("segment_frames=0", "segment_frames"),
    ("eps_cm=0.5", "--eps"),
])
def test_a_setting_it_cannot_take_is_one_usage_line(monkeypatch, capsys, pair, message):
    assert_refused_before_building(monkeypatch, capsys, ["--set", pair], message)


@pytest.mark.parametrize("kind, message", [
    ("full", "is not empty; pass --force"),
    ("link", "is a link"),
    ("file", "is not a folder"),
])
def test_a_keep_folder_it_would_overwrite_is_refused_before_anything_runs(monkeypatch, capsys, tmp_path, kind,
                                                                         message):
    keep = tmp_path / "keep"
    if kind == "full":
        keep.mkdir()
        (keep / "e1-0.5.txt").write_text("a manifest of an earlier run\n")
    elif kind == "link":
        (tmp_path / "elsewhere").mkdir()
        keep.symlink_to(tmp_path / "elsewhere")
    else:
        keep.write_text("not a folder")
    assert_refused_before_building(monkeypatch, capsys, ["--keep", str(keep)], message)
    if kind == "full":
        assert (keep / "e1-0.5.txt").read_text() == "a manifest of an earlier run\n"


def test_force_lets_a_full_keep_folder_through_the_check(monkeypatch, tmp_path):
    keep = tmp_path / "keep"
    keep.mkdir()
    (keep / "e1-0.5.txt").write_text("old")

    class Built(Exception):
        pass

    def build(*_):
        raise Built  # the check passed: the script went on to build its harness

    monkeypatch.setattr(runtime, "build_harness", build)
    with pytest.raises(Built):
        runtime.main(["--keep", str(keep), "--force"])


@pytest.mark.parametrize("cpu, asked, message", [
    (["sse4.1"], "avx2", "--isa avx2: this CPU does not run it (it runs sse4.1)"),
    ([], "sse4.1", "not x86-64"),
])
def test_an_instruction_set_the_cpu_lacks_is_one_usage_line(monkeypatch, capsys, cpu, asked, message):
    monkeypatch.setattr(runtime, "cpu_isas", lambda: cpu)
    assert_refused_before_building(monkeypatch, capsys, ["--isa", asked], message)


@pytest.mark.parametrize("isa, both, runtime_only", [
    ("sse4.1", ["-msse4.1"], ["-DMCBROT_NO_AVX2"]),
    ("avx2", ["-mavx2", "-mfma"], []),
])
def test_both_decoders_are_compiled_for_the_one_instruction_set(monkeypatch, tmp_path, isa, both, runtime_only):
    """The C runtime and the C++ harness (ACL's headers) get the same ISA flags; an SSE4.1 build leaves mcb-rot's
    runtime-dispatched AVX2 sums out, so neither decoder runs wider instructions than the other."""
    from types import SimpleNamespace

    from mocapbench.codecs import native_build
    from mocapbench.codecs.acl import build
    from mocapbench.codecs.mcb_rot import native

    commands = []
    monkeypatch.setattr(native_build, "cache_root", lambda: tmp_path)
    monkeypatch.setattr(build, "find_compiler", lambda: "c++")
    monkeypatch.setattr(native, "_compiler", lambda: "cc")
    monkeypatch.setattr(build, "find_acl_headers", lambda: SimpleNamespace(
        root=tmp_path, acl_include=tmp_path / "acl", rtm_include=tmp_path / "rtm"))
    monkeypatch.setattr(runtime.subprocess, "run", lambda command, **_: commands.append(command))
    runtime.build_harness(isa)
    compile_c, link_cxx = commands
    assert compile_c[0] == "cc" and link_cxx[0] == "c++"
    for flag in both:
        assert flag in compile_c and flag in link_cxx
    for flag in runtime_only:
        assert flag in compile_c and flag not in link_cxx
    other = {"sse4.1": "-mavx2", "avx2": "-DMCBROT_NO_AVX2"}[isa]
    assert other not in compile_c + link_cxx


@pytest.fixture(scope="module")
def harness(acl_codec, native_runtime):
    """The harness, built once (ACL's headers, a C and a C++ compiler: skipped where the ACL fixture skips)."""
    return runtime.build_harness()


@pytest.mark.parametrize("rig", ["moving root", "still root"])
def test_the_harness_samples_the_whole_pose_python_decodes(harness, tmp_path, monkeypatch, rig):
    """The pose the harness times (mcb-rot: ``mcbrot_sample_pose``; ACL: ``decompress_tracks``) is the pose Python
    decodes: mcb-rot's numpy reference decoder within 1e-9 (quaternions) and 1e-6 cm (translations), ACL's binding
    within float32 rounding; and ACL's buffer carries the game rig's translation tracks (the pelvis is metres from
    its offset, ACL's is within a centimetre of the clip's)."""
    from game_rig import game_rig_motion, still_root_rig

    from mocapbench.codecs import create
    from mocapbench.codecs.mcb_rot import native

    motion = game_rig_motion(75) if rig == "moving root" else still_root_rig(75)
    lines, _, _, refused = runtime._streams([motion], 0.5, tmp_path, "case", {})
    assert refused == [] and len(lines) == 1
    manifest = tmp_path / "case.txt"
    manifest.write_text(lines[0] + "\n")
    frame = 41
    poses = runtime.harness_poses(harness, manifest, frame)
    mcb, acl = lines[0].split()
    assert sorted(poses) == [("acl", mcb), ("mcb-rot", mcb)]

    monkeypatch.setattr(native, "library", lambda: None)  # the numpy decoder, the reference
    reference = create("mcb-rot").decode(Path(mcb).read_bytes()).motion
    rotations, translations = poses[("mcb-rot", mcb)]
    assert rotations.shape == (22, 4) and translations.shape == (22, 3)
    np.testing.assert_allclose(rotations, reference.rotations[frame], rtol=0, atol=1e-9)
    np.testing.assert_allclose(translations, reference.local_translations()[frame], rtol=0, atol=1e-6)

    acl_rotations, acl_translations = poses[("acl", mcb)]
    acl_stream = create("acl", precision_cm=0.5).encode(motion)
    assert Path(acl).read_bytes() in acl_stream  # the buffer the harness read, in the stream Python decodes
    acl_reference = create("acl").decode(acl_stream).motion
    same_sign = np.sign(np.sum(acl_rotations * acl_reference.rotations[frame], axis=1))[:, None]
    np.testing.assert_allclose(acl_rotations * same_sign, acl_reference.rotations[frame], rtol=0, atol=1e-6)
    np.testing.assert_allclose(acl_translations, acl_reference.local_translations()[frame], rtol=0, atol=1e-4)
    source = motion.local_translations()[frame]
    hips = motion.skeleton.index("Hips")
    assert np.abs(source[hips] - motion.skeleton.offsets[hips]).max() > 100.0
    assert np.abs(acl_translations[hips] - source[hips]).max() < 1.0
    assert np.abs(translations[hips] - source[hips]).max() < 1.0


def test_a_bad_manifest_is_one_line_and_a_non_zero_exit(harness, tmp_path):
    """A manifest line that is not two readable files stops the harness before anything is timed: one line naming
    the manifest's line, exit 2 (and :class:`runtime.HarnessError` from Python); a stream a decoder refuses is one
    line naming the file, exit 1, the other clips still measured (ACL's buffer of that clip left out too)."""
    import subprocess

    from game_rig import game_rig_motion

    lines, _, _, _ = runtime._streams([game_rig_motion(30)], 1.0, tmp_path, "ok", {})
    cases = {"one field": f"{lines[0]}\n{lines[0].split()[0]}\n",
             "missing file": f"{lines[0]}\n{tmp_path / 'nowhere.mcb'} {lines[0].split()[1]}\n",
             "three fields": f"{lines[0]} extra\n"}
    expected = {"one field": "line 2: expected two paths", "missing file": "line 2: cannot read",
                "three fields": "line 1: expected two paths"}
    for case, text in cases.items():
        manifest = tmp_path / f"{case.replace(' ', '-')}.txt"
        manifest.write_text(text)
        result = subprocess.run([str(harness), str(manifest), "1"], capture_output=True, text=True)
        assert result.returncode == 2, case
        assert result.stdout == "", case
        assert result.stderr.count("\n") == 1 and expected[case] in result.stderr, (case, result.stderr)
        with pytest.raises(runtime.HarnessError, match=expected[case]):
            runtime.harness_poses(harness, manifest, 0)

    garbage = tmp_path / "garbage.mcb"
    garbage.write_bytes(b"MCB" + bytes(60))
    manifest = tmp_path / "refused.txt"
    manifest.write_text(f"{garbage} {lines[0].split()[1]}\n{lines[0]}\n")
    result = subprocess.run([str(harness), str(manifest), "1"], capture_output=True, text=True)
    assert result.returncode == 1
    assert result.stderr.count("\n") == 1 and str(garbage) in result.stderr
    decoders = [line.split()[0] for line in result.stdout.splitlines()]
    assert decoders == ["mcb-rot", "acl"]  # the good clip only: ACL is not timed on the clip mcb-rot refused


def test_sample_times_mcbrot_sample_beside_the_whole_pose(harness, tmp_path):
    """``--sample``: a third row per clip (``mcb-rot-sample``), parsed by the script beside the two decoders'."""
    from game_rig import game_rig_motion

    lines, _, _, _ = runtime._streams([game_rig_motion(20)], 1.0, tmp_path, "ok", {})
    rows = runtime._run(harness, lines, tmp_path / "ok.txt", 1, runs=2, sample=True)
    assert [row["decoder"] for row in rows] == ["mcb-rot", "mcb-rot-sample", "acl"]
    assert all(row["frames"] == 20 and row["joints"] == 22 and row["fwd_warm"] > 0 for row in rows)


def test_a_missing_data_folder_is_one_line(monkeypatch, tmp_path, capsys):
    from mocapbench.benchmarks.entry import run_script

    monkeypatch.setattr(runtime, "build_harness", lambda *_: tmp_path / "no-harness")
    monkeypatch.setenv("MOCAPBENCH_BANDAI_DIR", str(tmp_path / "no-bandai-here"))
    assert run_script(lambda: runtime.main(["--dataset", "bandai_test"])) == 2
    error = capsys.readouterr().err.strip().splitlines()
    assert len(error) == 1 and str(tmp_path / "no-bandai-here") in error[0]
