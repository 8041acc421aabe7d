"""The one table of motion formats and the one place a folder becomes motion files."""

from __future__ import annotations

from mocapbench.io.format_table import READ_SUFFIXES, WRITE_SUFFIXES, default_unit_source, motion_files


def test_a_folder_gives_its_files_of_every_readable_format_in_name_order(tmp_path):
    for name in ("b.fbx", "a.bvh", "c.glb", "d.gltf", "e.amc", "notes.txt", "f.BVH"):
        (tmp_path / name).write_text("x")
    (tmp_path / "sub.bvh").mkdir()  # a folder with a motion suffix is not a file
    listed = [path.name for path in motion_files([tmp_path])]
    assert listed == ["a.bvh", "b.fbx", "c.glb", "d.gltf", "e.amc", "f.BVH"]


def test_a_file_is_taken_as_given_and_a_folder_can_be_narrowed(tmp_path):
    (tmp_path / "a.bvh").write_text("x")
    (tmp_path / "b.fbx").write_text("x")
    other = tmp_path / "clip.any"
    assert motion_files([other, tmp_path], suffixes=(".bvh",)) == [other, tmp_path / "a.bvh"]


def test_every_written_format_is_read_and_every_read_format_says_where_its_unit_comes_from():
    assert set(WRITE_SUFFIXES) <= set(READ_SUFFIXES)
    assert ".fbx" in READ_SUFFIXES
    for suffix in READ_SUFFIXES:
        assert default_unit_source(f"clip{suffix}") != default_unit_source("clip.unknown")


def test_read_motion_and_write_motion_dispatch_through_the_table(tmp_path, monkeypatch):
    """A format is one row: a row added to the table is read and written through the one entry point."""
    from mocapbench.io.format_table import FORMATS, MotionFormat
    from mocapbench.io.formats import read_motion, write_motion
    from mocapbench.synthetic import sinusoidal_motion

    seen = {}

    def read(path, request):
        seen["read"] = (path, request.unit_cm, request.fps)
        return sinusoidal_motion(num_frames=8), 2.0, "z"

    def write(motion, path, unit_cm, force):
        seen["write"] = (path, unit_cm, force)
        return path

    monkeypatch.setitem(FORMATS, ".toy", MotionFormat(read, write, "the toy's own"))
    (tmp_path / "clip.toy").write_text("x")
    motion, _ = read_motion(tmp_path / "clip.toy", fps=30)
    assert seen["read"] == (tmp_path / "clip.toy", None, 30)
    assert motion.source_unit_cm == 2.0 and motion.up_axis == "z"
    assert write_motion(motion, tmp_path / "out.toy", units="m", force=True) == tmp_path / "out.toy"
    assert seen["write"] == (tmp_path / "out.toy", 100.0, True)
    assert default_unit_source("clip.toy") == "the toy's own"
