"""Safe outputs: atomic, never through a link, nothing replaced without force, no temporary left on failure."""

from __future__ import annotations

import os

import numpy as np
import pytest

from mocapbench.cli import main
from mocapbench.io import read_bvh, write_bvh
from mocapbench.io.safe_output import (
    OutputError,
    OutputExistsError,
    check_name,
    open_output,
    save_npy,
    write_bytes,
    write_text,
)
from mocapbench.synthetic import sinusoidal_motion


def leftovers(folder) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(".tmp"))


def test_write_creates_the_file_with_the_usual_permissions(tmp_path):
    path = write_bytes(tmp_path / "a.mcb", b"abc")
    assert path.read_bytes() == b"abc"
    mask = os.umask(0)
    os.umask(mask)
    assert path.stat().st_mode & 0o777 == 0o666 & ~mask
    assert leftovers(tmp_path) == []


def test_existing_file_is_refused_without_force_and_replaced_with_it(tmp_path):
    path = tmp_path / "a.txt"
    path.write_text("old")
    with pytest.raises(OutputExistsError, match="a.txt exists; pass --force"):
        write_text(path, "new")
    assert path.read_text() == "old"
    write_text(path, "new", force=True)
    assert path.read_text() == "new"
    assert leftovers(tmp_path) == []


@pytest.mark.parametrize("force", [False, True])
def test_a_link_to_a_file_is_never_written_through(tmp_path, force):
    target = tmp_path / "precious.txt"
    target.write_text("keep me")
    link = tmp_path / "out.bvh"
    link.symlink_to(target)
    if force:
        write_text(link, "decoded", force=True)
        assert not link.is_symlink() and link.read_text() == "decoded"  # the link itself was replaced
    else:
        with pytest.raises(OutputExistsError, match="is a link"):
            write_text(link, "decoded")
        assert link.is_symlink()
    assert target.read_text() == "keep me"


@pytest.mark.parametrize("force", [False, True])
def test_a_dangling_link_never_creates_its_target(tmp_path, force):
    target = tmp_path / "elsewhere" / "created.txt"
    (tmp_path / "elsewhere").mkdir()
    link = tmp_path / "out.npy"
    link.symlink_to(target)
    if force:
        save_npy(link, np.arange(3.0), force=True)
        assert not link.is_symlink()
        np.testing.assert_array_equal(np.load(link), np.arange(3.0))
    else:
        with pytest.raises(OutputExistsError, match="is a link"):
            save_npy(link, np.arange(3.0))
    assert not target.exists()


def test_a_folder_is_refused_even_with_force(tmp_path):
    (tmp_path / "d").mkdir()
    with pytest.raises(OutputError, match="is a folder"):
        write_bytes(tmp_path / "d", b"x", force=True)
    with pytest.raises(OutputError, match="does not exist"):
        write_bytes(tmp_path / "missing" / "x.mcb", b"x")


def test_failure_while_writing_removes_the_temporary_and_keeps_the_old_file(tmp_path):
    path = tmp_path / "a.npy"
    path.write_bytes(b"old")
    with pytest.raises(RuntimeError, match="disk full"):
        with open_output(path, "wb", force=True) as file:
            file.write(b"half")
            raise RuntimeError("disk full")
    assert path.read_bytes() == b"old"
    assert leftovers(tmp_path) == []


def test_a_failing_npy_save_leaves_no_temporary(tmp_path):
    with pytest.raises(ValueError):
        save_npy(tmp_path / "x.npy", np.array([object()], dtype=object))  # pickling refused
    assert list(tmp_path.iterdir()) == []


def test_a_name_appearing_during_the_write_is_not_replaced(tmp_path):
    path = tmp_path / "race.txt"
    with pytest.raises(OutputExistsError, match="appeared while it was written"):
        with open_output(path, "w") as file:
            file.write("mine")
            path.write_text("theirs")
    assert path.read_text() == "theirs"
    assert leftovers(tmp_path) == []


@pytest.mark.parametrize("name", ["a/b", "../up", "..", ".", "", "x\\y", "nul\0", "-rf", "x" * 200])
def test_bad_names_are_refused_in_one_line(name):
    with pytest.raises(ValueError, match="report name") as error:
        check_name(name, "report name")
    assert "\n" not in str(error.value)


def test_plain_names_pass():
    assert check_name("cmu-run_2 (final)", "report name") == "cmu-run_2 (final)"


def test_write_bvh_refuses_links_and_round_trips(tmp_path):
    motion = sinusoidal_motion(num_frames=5)
    target = tmp_path / "precious.bvh"
    target.write_text("keep me")
    link = tmp_path / "out.bvh"
    link.symlink_to(target)
    with pytest.raises(FileExistsError, match="is a link"):
        write_bvh(motion, link)
    write_bvh(motion, link, overwrite=True)
    assert target.read_text() == "keep me"
    assert read_bvh(link).num_frames == 5


def _stream(tmp_path, codec="quant-rot-zstd"):
    bvh = write_bvh(sinusoidal_motion(num_frames=8), tmp_path / "walk.bvh")
    stream = tmp_path / "walk.mcb"
    assert main(["compress", str(bvh), str(stream), "--codec", codec]) == 0
    return stream


@pytest.mark.parametrize("suffix", [".bvh", ".npy", ".mcb"])
@pytest.mark.parametrize("dangling", [False, True])
def test_cli_never_writes_through_a_link(tmp_path, capsys, suffix, dangling):
    stream = _stream(tmp_path)
    target = tmp_path / f"target{suffix}"
    if not dangling:
        target.write_text("keep me")
    link = tmp_path / f"out{suffix}"
    link.symlink_to(target)
    if suffix == ".mcb":
        argv = ["compress", str(tmp_path / "walk.bvh"), str(link), "--codec", "raw-zstd"]
    else:
        argv = ["decompress", str(stream), str(link)]
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "is a link" in err and err.count("\n") == 1
    assert main([*argv, "--force"]) == 0
    assert not link.is_symlink() and link.stat().st_size > 0
    assert target.read_text() == "keep me" if not dangling else not target.exists()
    assert leftovers(tmp_path) == []


def test_report_name_with_a_separator_is_a_one_line_error(tmp_path, capsys):
    from mocapbench.experiments.report import _main

    with pytest.raises(SystemExit) as exit_:
        _main([str(tmp_path), "--name", "a/b", "--reports-root", str(tmp_path / "reports")])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert "report name 'a/b' holds '/'" in err
    assert not (tmp_path / "reports").exists()
