"""A write killed with -9 leaves a hidden temporary; the next write to that name removes it, and nothing else."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from mocapbench.io import safe_output
from mocapbench.io.safe_output import write_bytes

pytestmark = pytest.mark.skipif(safe_output.fcntl is None, reason="stale temporaries are told apart with flock")

ROOT = Path(__file__).resolve().parents[1]
# A write that blocks after its temporary exists (and is locked), until it is killed.
HANGING_WRITE = """
import sys, time
from mocapbench.io.safe_output import open_output
with open_output(sys.argv[1], "wb") as file:
    file.write(b"partial")
    file.flush()
    print("writing", flush=True)
    time.sleep(600)
"""


def _temporaries(folder: Path, name: str) -> list[Path]:
    return sorted(p for p in folder.iterdir() if p.name.startswith(f".{name}.") and p.name.endswith(".tmp"))


def _age(path: Path, seconds: float = 10.0) -> None:
    past = time.time() - seconds
    os.utime(path, (past, past), follow_symlinks=False)


def _start_hanging_write(target: Path) -> subprocess.Popen:
    process = subprocess.Popen([sys.executable, "-c", HANGING_WRITE, str(target)], stdout=subprocess.PIPE,
                               env={**os.environ, "PYTHONPATH": str(ROOT)}, text=True)
    assert process.stdout.readline().strip() == "writing"
    return process


def test_the_temporary_of_a_write_killed_with_9_is_removed_by_the_next_write(tmp_path):
    target = tmp_path / "out.mcb"
    process = _start_hanging_write(target)
    process.send_signal(signal.SIGKILL)
    process.wait()
    (left,) = _temporaries(tmp_path, "out.mcb")
    assert not target.exists() and left.read_bytes() == b"partial"
    _age(left)
    write_bytes(target, b"whole")
    assert target.read_bytes() == b"whole" and _temporaries(tmp_path, "out.mcb") == []


def test_the_temporary_of_a_live_write_is_kept(tmp_path):
    target = tmp_path / "out.mcb"
    process = _start_hanging_write(target)
    try:
        (live,) = _temporaries(tmp_path, "out.mcb")
        _age(live)
        write_bytes(tmp_path / "out.mcb", b"other", force=True)
        assert live.exists(), "a live write's temporary was removed"
    finally:
        process.kill()
        process.wait()


def test_a_young_temporary_is_kept(tmp_path):
    young = tmp_path / ".out.mcb.abcd1234.tmp"
    young.write_bytes(b"x")
    write_bytes(tmp_path / "out.mcb", b"whole")
    assert young.exists()


def test_only_our_own_pattern_for_that_name_is_removed_and_links_are_never_followed(tmp_path):
    outside = tmp_path / "outside"
    outside.mkdir()
    victim = outside / "victim.bin"
    victim.write_bytes(b"keep me")
    folder = tmp_path / "out"
    folder.mkdir()
    stale = folder / ".out.mcb.abcd1234.tmp"
    others = [
        folder / ".out.mcb.abcd123.tmp",  # 7 random characters: not mkstemp's
        folder / ".out.mcb.ABCD1234.tmp",  # upper case: not mkstemp's
        folder / ".other.mcb.abcd1234.tmp",  # another target's
        folder / "out.mcb.abcd1234.tmp",  # not hidden
        folder / ".out.mcb.abcd1234.tmp.bak",
    ]
    for path in (stale, *others):
        path.write_bytes(b"x")
        _age(path)
    link = folder / ".out.mcb.zzzz9999.tmp"
    os.symlink(victim, link)
    _age(link)
    subfolder = folder / ".out.mcb.dddd0000.tmp"
    subfolder.mkdir()
    write_bytes(folder / "out.mcb", b"whole")
    assert not stale.exists()
    assert all(path.exists() for path in others)
    assert link.is_symlink() and victim.read_bytes() == b"keep me"
    assert subfolder.is_dir()
