"""``mocapbench view``: a player page for a motion file or a stream, against its original or alone."""

from __future__ import annotations

import json
import re

import pytest

from mocapbench.cli import main
from mocapbench.io import write_bvh


@pytest.fixture
def bvh_file(tmp_path, synthetic_motion):
    path = tmp_path / "walk.bvh"
    write_bvh(synthetic_motion, path)
    return path


def _data(page):
    return json.loads(re.search(r'id="player-data">(.*?)</script>', page.read_text(), re.S).group(1))


def test_a_stream_against_its_original_marks_the_worst_joint(tmp_path, bvh_file, capsys):
    stream = tmp_path / "walk.mcb"
    assert main(["compress", str(bvh_file), str(stream), "--codec", "mcb-linf", "--set", "eps_cm=1.0"]) == 0
    page = tmp_path / "walk.html"
    assert main(["view", str(stream), "--against", str(bvh_file), "-o", str(page)]) == 0
    assert "player page of walk.mcb against walk.bvh" in capsys.readouterr().out
    (entry,) = _data(page)["entries"]
    assert entry["decoded"] is not None and 0 < entry["max_err_cm"] <= 1.0 + 1e-4
    assert entry["worst_frame"] is not None and entry["worst_joint"] is not None
    text = page.read_text()
    assert "<script src=" not in text and "function floats" in text  # the script is inside: the page stands alone


def test_a_motion_file_alone_and_a_rotation_stream_alone(tmp_path, bvh_file):
    assert main(["view", str(bvh_file)]) == 0
    (entry,) = _data(tmp_path / "walk.bvh.html")["entries"]
    assert entry["decoded"] is None and entry["worst_frame"] is None
    stream = tmp_path / "rot.mcb"
    assert main(["compress", str(bvh_file), str(stream), "--codec", "quant-rot-zstd"]) == 0
    assert main(["view", str(stream), "-o", str(tmp_path / "rot.html")]) == 0
    assert len(_data(tmp_path / "rot.html")["entries"][0]["names"]) == 31


def test_errors_are_one_line(tmp_path, bvh_file, synthetic_motion, capsys):
    stream = tmp_path / "walk.mcb"
    assert main(["compress", str(bvh_file), str(stream), "--codec", "mcb-linf"]) == 0
    assert main(["view", str(stream)]) == 2
    assert "joint positions only" in capsys.readouterr().err
    short = tmp_path / "short.bvh"
    write_bvh(synthetic_motion.slice(0, 10), short)
    assert main(["view", str(stream), "--against", str(short)]) == 2
    assert "must match" in capsys.readouterr().err
    assert main(["view", str(bvh_file), "-o", str(tmp_path / "x.html")]) == 0
    assert main(["view", str(bvh_file), "-o", str(tmp_path / "x.html")]) == 2  # no overwrite without --force
    assert main(["view", str(bvh_file), "-o", str(tmp_path / "x.html"), "--force"]) == 0
    assert main(["view", str(tmp_path / "missing.bvh")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "missing.bvh" in err[-1]
