"""The package's floors, drawn from its imports: no import circle, no arrow back up, a short package root.

Every ``import`` of a ``mocapbench`` module counts, those inside functions too (a lazy import is still a
dependency). ``from package import name`` counts as an arrow to the sub-module ``name`` when there is one, else to
the package's ``__init__``.
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "mocapbench"

#: The floors, lowest first: a module may import its own top-level package and any lower floor, never a higher
#: floor or another package of its own floor. A module named here sits on its own floor, below its package: the
#: container and the decode limits are the stream's own format and bounds (they import only entropy's errors),
#: which the motion readers honour too.
FLOORS = (
    {"mocapbench.lazy_imports"},
    {"mocapbench.motion", "mocapbench.entropy", "mocapbench.metrics"},
    {"mocapbench.codecs.container", "mocapbench.codecs.limits"},
    {"mocapbench.io"},
    {"mocapbench.synthetic", "mocapbench.datasets"},
    {"mocapbench.codecs"},
    {"mocapbench.ratesearch", "mocapbench.fuzz"},
    {"mocapbench.experiments"},
    {"mocapbench.cli"},
    {"mocapbench.benchmarks", "mocapbench.__main__"},
)
#: Modules any module may import: the package's face (its version) and its configs (package data).
ANYWHERE = {"mocapbench", "mocapbench.configs"}
ROOT_MODULES_MAX = 5


def _modules() -> dict[str, Path]:
    modules = {}
    for path in PACKAGE.rglob("*.py"):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        modules[".".join(parts)] = path
    return modules


def _imports(modules: dict[str, Path]) -> dict[str, set[str]]:
    """Module -> the mocapbench modules it imports (anywhere in its body)."""
    graph = {}
    for name, path in modules.items():
        targets = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                found = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                found = [f"{node.module}.{alias.name}" for alias in node.names]
                found = [target if target in modules else node.module for target in found]
            else:
                continue
            for target in found:
                while target and target not in modules:
                    target = target.rpartition(".")[0]
                if target and target != name:
                    targets.add(target)
        graph[name] = targets
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    index, low, on_stack, stack, found, counter = {}, {}, set(), [], [], 0
    for start in graph:
        if start in index:
            continue
        work = [(start, iter(sorted(graph[start])))]
        index[start] = low[start] = counter
        counter += 1
        stack.append(start)
        on_stack.add(start)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return found


def _top(name: str) -> str:
    return ".".join(name.split(".")[:2])


def _floor(name: str) -> int | None:
    """The floor of the most specific entry of :data:`FLOORS` that ``name`` is or lies in."""
    while name:
        level = next((level for level, floor in enumerate(FLOORS) if name in floor), None)
        if level is not None:
            return level
        name = name.rpartition(".")[0]
    return None


def test_no_module_imports_itself_round_a_circle():
    assert _cycles(_imports(_modules())) == []


def test_the_cycle_finder_sees_a_circle():
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_every_top_level_package_has_a_floor():
    unplaced = sorted({_top(name) for name in _modules() if _floor(name) is None} - ANYWHERE)
    assert unplaced == [], f"add {unplaced} to FLOORS in {__file__}"


def test_no_arrow_runs_back_up_or_sideways():
    upward = []
    for name, targets in _imports(_modules()).items():
        for target in targets:
            if _top(target) == _top(name) or target in ANYWHERE or _top(name) in ANYWHERE:
                continue
            if _floor(target) >= _floor(name):
                upward.append(f"{name} -> {target}")
    assert upward == []


def test_no_module_imports_the_face_of_its_own_package():
    """A package's ``__init__`` re-exports its modules; a module inside imports its siblings directly."""
    modules = _modules()
    back = []
    for name, targets in _imports(modules).items():
        for target in targets:
            is_package = modules[target].name == "__init__.py"
            if is_package and target != "mocapbench" and name.startswith(target + "."):
                back.append(f"{name} -> {target}")
    assert back == []


def test_the_package_root_holds_few_modules():
    root = sorted(path.stem for path in PACKAGE.glob("*.py") if path.stem not in ("__init__", "__main__"))
    assert len(root) <= ROOT_MODULES_MAX, root
