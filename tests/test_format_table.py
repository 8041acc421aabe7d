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
