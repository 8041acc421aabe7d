"""Every codec family folder's package docstring lists its modules, all of them and only them.

The list is written by hand (a sentence of design per module reads better than a generated one), so this test is
what keeps it from drifting: a module added, renamed or removed without its line fails here.
"""

import ast
from pathlib import Path

import pytest

CODECS = Path(__file__).resolve().parents[2] / "mocapbench" / "codecs"
FAMILIES = sorted(path.parent for path in CODECS.glob("*/__init__.py"))


def listed_modules(docstring: str) -> set[str]:
    """The names under the numpydoc-style ``Modules`` heading: unindented lines up to the next heading or the end."""
    lines = docstring.splitlines()
    start = next(i for i, line in enumerate(lines) if line == "Modules" and lines[i + 1].startswith("---")) + 2
    names = set()
    for i in range(start, len(lines)):
        line = lines[i]
        if i + 1 < len(lines) and lines[i + 1].startswith("---"):
            break
        if line and not line[0].isspace():
            names.add(line.strip())
    return names


def test_every_family_folder_is_found():
    assert {path.name for path in FAMILIES} >= {"acl", "baselines", "lsdt", "mcb_linf", "mcb_rot", "neural_fourier",
                                                "pga"}


@pytest.mark.parametrize("family", FAMILIES, ids=lambda path: path.name)
def test_package_docstring_lists_every_module_of_the_family(family: Path):
    docstring = ast.get_docstring(ast.parse((family / "__init__.py").read_text(encoding="utf-8")))
    assert docstring and "\nModules\n-------\n" in docstring, f"{family.name}/__init__.py: no 'Modules' section"
    on_disk = {path.stem for path in family.glob("*.py") if path.stem != "__init__"}
    on_disk |= {path.name for path in family.iterdir() if (path / "__init__.py").is_file()}
    listed = listed_modules(docstring)
    assert not on_disk - listed, f"{family.name}/__init__.py does not list {sorted(on_disk - listed)}"
    assert not listed - on_disk, f"{family.name}/__init__.py lists missing modules {sorted(listed - on_disk)}"


def test_a_missing_module_is_noticed():
    docstring = "Title.\n\nModules\n-------\ncodec\n    The codec.\nstream\n    Its stream.\n"
    assert listed_modules(docstring) == {"codec", "stream"}
    assert listed_modules(docstring + "\nNotes\n-----\nother\n") == {"codec", "stream"}
