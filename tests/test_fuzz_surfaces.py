"""The fuzz harness's file surfaces: seeds that read, deterministic hostile variants, saved findings that stay clean."""

from __future__ import annotations

import warnings

import pytest

from mocapbench.codecs.limits import DecodeLimits
from mocapbench.fuzz import REGRESSION_DIR
from mocapbench.fuzz.surfaces import SURFACES, clean_errors, file_mutations, read_input, seed_files

FILE_REGRESSIONS = sorted(p for p in REGRESSION_DIR.iterdir() if p.suffix in set(SURFACES.values()))


@pytest.fixture(scope="module")
def seeds():
    return seed_files()


def test_every_seed_reads_and_every_surface_but_fbx_has_seeds(seeds, tmp_path):
    assert {"bvh", "gltf", "glb", "model"} <= set(seeds)
    for surface, files in seeds.items():
        assert len(files) >= 2
        for data in files:
            assert read_input(surface, data, tmp_path, DecodeLimits()) > 0


@pytest.mark.parametrize("surface", sorted(SURFACES))
def test_hostile_files_are_deterministic_and_differ_from_their_seed(seeds, surface):
    if surface not in seeds:
        pytest.skip(f"no {surface} seed here (FBX needs the ufbx package)")
    seed = seeds[surface][0]
    first = list(file_mutations(surface, seed, 24, 7))
    assert first == list(file_mutations(surface, seed, 24, 7))
    assert {kind for kind, _ in first} == {"mutated", "generated"}
    assert sum(data != seed for _, data in first) >= 22


def test_a_read_is_confined_to_its_folder(seeds, tmp_path):
    """A glTF naming a file beside it finds only its own input there (the worker's folder holds nothing else)."""
    (tmp_path / "input.bvh").write_bytes(seeds["bvh"][0])
    read_input("gltf", seeds["gltf"][0], tmp_path, DecodeLimits())
    assert [p.name for p in tmp_path.iterdir()] == ["input.gltf"]


@pytest.mark.parametrize("path", FILE_REGRESSIONS, ids=lambda p: p.name)
def test_every_saved_file_finding_is_read_or_refused_in_one_line(path, tmp_path):
    surface = path.name.rsplit("-", 1)[0]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a warning is a line the user sees that says nothing
        try:
            read_input(surface, path.read_bytes(), tmp_path, DecodeLimits(max_output_bytes=256 << 20))
        except clean_errors() as error:
            assert "\n" not in str(error)
