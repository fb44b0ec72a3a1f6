"""The dependency order of DESIGN.md, checked on every module's imports.

``models <- estimation <- planning <- diagrams <- experiments <- cmanip``: a module may
import its own layer and the layers to its left, never one to its right. Only
``diagrams/`` may import ``pydrake.systems``; the generic POMDP library
(``planning/pomdp``) imports no model of ours (only itself and the planner seam,
``planning.protocols``); and no two modules import each other,
directly or round a longer loop. Imports inside functions count as much as those at the
top: a lazy import is still a dependency. Each failure names the file and the line.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
LAYERS = ("models", "estimation", "planning", "diagrams", "experiments", "cmanip")
RANK = {name: rank for rank, name in enumerate(LAYERS)}


def module_name(path: Path, root: Path = ROOT) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def imports_of(path: Path, root: Path = ROOT) -> list[tuple[str, tuple[str, ...], int]]:
    """(imported module, names taken from it, line) for every import statement in ``path``,
    relative imports resolved; the names may be submodules (``from pkg import module``)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    package = module_name(path, root).split(".")
    if path.name != "__init__.py":
        package = package[:-1]
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(alias.name, (), node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package[:len(package) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            found.append((base, tuple(alias.name for alias in node.names), node.lineno))
    return found


def project_modules(root: Path = ROOT) -> dict[str, Path]:
    return {module_name(p, root): p for layer in LAYERS for p in (root / layer).rglob("*.py")}


def layer_violations(root: Path = ROOT) -> list[str]:
    """Every import against the layer order, of ``pydrake.systems`` outside ``diagrams``,
    or of our models from the generic POMDP library, as ``file:line: message``."""
    problems = []
    for name, path in sorted(project_modules(root).items()):
        layer = name.split(".")[0]
        where = path.relative_to(root)
        for target, _, line in imports_of(path, root):
            top = target.split(".")[0]
            if top in RANK and RANK[top] > RANK[layer]:
                problems.append(f"{where}:{line}: {layer} imports {target} ({top} is a "
                                f"later layer: {' <- '.join(LAYERS)})")
            if (target == "pydrake.systems" or target.startswith("pydrake.systems.")) \
                    and layer != "diagrams":
                problems.append(f"{where}:{line}: imports {target}; only diagrams/ may "
                                "define or use Drake systems")
            if name.startswith("planning.pomdp") and top in RANK and \
                    not target.startswith("planning.pomdp") and target != "planning.protocols":
                problems.append(f"{where}:{line}: the generic POMDP library imports "
                                f"{target}; it may import only planning.pomdp and the "
                                "planner seam, planning.protocols")
    return problems


def import_cycles(root: Path = ROOT) -> list[str]:
    """Each cycle of imports between project modules, as ``a -> b -> a`` with the file and
    line of each edge."""
    modules = project_modules(root)
    edges: dict[str, dict[str, int]] = {}
    for name, path in modules.items():
        targets = {}
        for base, names, line in imports_of(path, root):
            # ``from pkg import module`` depends on the module too
            for target in (base, *(f"{base}.{n}" for n in names)):
                if target in modules and target != name:
                    targets.setdefault(target, line)
        edges[name] = targets
    # Tarjan's strongly connected components; any component of two or more is a cycle.
    index, low, stack, on_stack, components = {}, {}, [], set(), []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in edges[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                components.append(sorted(component))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    problems = []
    for component in components:
        members = set(component)
        links = [f"{modules[a].relative_to(root)}:{line} imports {b}"
                 for a in component for b, line in edges[a].items() if b in members]
        problems.append(f"import cycle among {', '.join(component)}: " + "; ".join(links))
    return problems


def test_dependencies_follow_the_layer_order():
    problems = layer_violations()
    assert not problems, "\n".join(problems)


def test_no_import_cycles():
    problems = import_cycles()
    assert not problems, "\n".join(problems)


@pytest.fixture
def fake_tree(tmp_path: Path) -> Path:
    for layer in LAYERS:
        (tmp_path / layer).mkdir()
        (tmp_path / layer / "__init__.py").write_text("")
    return tmp_path


def test_a_backward_import_is_named_with_its_file_and_line(fake_tree):
    (fake_tree / "models" / "shape.py").write_text(
        '"""doc"""\n\n\ndef f():\n    from planning.solver import x\n    return x\n')
    (fake_tree / "planning" / "solver.py").write_text("x = 1\n")
    problems = layer_violations(fake_tree)
    assert len(problems) == 1
    assert problems[0].startswith("models/shape.py:5: models imports planning.solver")


def test_drake_systems_outside_diagrams_and_models_in_the_pomdp_library_are_named(fake_tree):
    (fake_tree / "estimation" / "f.py").write_text("from pydrake.systems.framework import "
                                                   "LeafSystem\n")
    (fake_tree / "planning" / "pomdp").mkdir()
    (fake_tree / "planning" / "pomdp" / "solver.py").write_text("import models.shape\n")
    (fake_tree / "diagrams" / "ok.py").write_text("from pydrake.systems.framework import "
                                                  "LeafSystem\n")
    problems = layer_violations(fake_tree)
    assert len(problems) == 2
    assert problems[0].startswith("estimation/f.py:1: imports pydrake.systems.framework")
    assert problems[1].startswith("planning/pomdp/solver.py:1: the generic POMDP library")


def test_a_cycle_is_named_with_both_edges(fake_tree):
    (fake_tree / "experiments" / "a.py").write_text("from experiments import b\n")
    (fake_tree / "experiments" / "b.py").write_text("\n\ndef g():\n    from .a import x\n")
    problems = import_cycles(fake_tree)
    assert len(problems) == 1
    assert "experiments/a.py:1 imports experiments.b" in problems[0]
    assert "experiments/b.py:4 imports experiments.a" in problems[0]
