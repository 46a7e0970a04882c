"""The package's shape: the paper's core imports nothing above it, every layer imports only the
layers below it, and no import, at the top of a module or inside a function, closes a cycle."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[1] / "paper_repro"

LAYERS = (
    {"config", "config_history", "presets", "validation", "paths", "progress",
     "_native", "_blas"},  # imported by all
    {"vehicles"},
    {"problem"},
    {"solvers"},
    {"world"},
    {"sim"},
    {"analysis"},
    {"evidence"},
    {"studies"},
    {"plots"},
    {"book"},
    {"cli", "__main__"},
)
"""From the bottom up. The paper's core is the layers up to ``solvers``."""

CORE = {"vehicles", "problem", "solvers"}
ABOVE_THE_CORE = {"world", "sim", "analysis", "evidence", "studies", "plots", "book", "cli"}


def _modules() -> dict[str, Path]:
    """Dotted name -> file, for every module of the package (a package is its __init__)."""
    out = {}
    for path in ROOT.rglob("*.py"):
        parts = path.relative_to(ROOT.parent).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _import_graph() -> dict[str, set[str]]:
    """Module -> the package's modules it imports, anywhere in it (functions included).
    ``from paper_repro.a import b`` is an import of ``paper_repro.a.b`` when that is a module,
    else of ``paper_repro.a``."""
    modules = _modules()
    graph = {}
    for name, path in modules.items():
        deps = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                assert node.level == 0, f"{name}: relative import (the package imports absolutely)"
                if not (node.module or "").startswith("paper_repro"):
                    continue
                for alias in node.names:
                    sub = f"{node.module}.{alias.name}"
                    deps.add(sub if sub in modules else node.module)
            elif isinstance(node, ast.Import):
                deps |= {a.name for a in node.names if a.name.startswith("paper_repro")}
        graph[name] = deps - {name}
    return graph


def _layer(module: str) -> int:
    part = module.split(".")[1] if "." in module else ""
    return next(i for i, layer in enumerate(LAYERS) if part in layer)


def _find_cycle(graph):
    state = {}

    def visit(m, trail):
        state[m] = "open"
        for d in sorted(graph.get(m, ())):
            if state.get(d) == "open":
                return trail[trail.index(d):] + [d] if d in trail else trail + [d]
            if d not in state and (cycle := visit(d, trail + [d])):
                return cycle
        state[m] = "done"
        return None

    for m in sorted(graph):
        if m not in state and (cycle := visit(m, [m])):
            return cycle
    return None


GRAPH = _import_graph()
INSIDE = {m: d for m, d in GRAPH.items() if m != "paper_repro"}  # the top-level __init__ is the API


def test_every_module_has_a_layer():
    for module in INSIDE:
        _layer(module)  # raises StopIteration for a folder no layer names


def test_no_import_anywhere_closes_a_cycle():
    assert _find_cycle(INSIDE) is None


def test_the_core_imports_nothing_above_it():
    for module, deps in INSIDE.items():
        if module.split(".")[1] in CORE:
            above = {d for d in deps if d.split(".")[1] in ABOVE_THE_CORE}
            assert not above, f"{module} imports {sorted(above)}"


@pytest.mark.parametrize("module", sorted(INSIDE))
def test_a_module_imports_only_its_layer_and_the_layers_below(module):
    upward = {d for d in INSIDE[module] if d != "paper_repro" and _layer(d) > _layer(module)}
    assert not upward, f"{module} imports the higher layer(s) of {sorted(upward)}"
    assert "paper_repro" not in INSIDE[module], f"{module} imports the top-level package"


SENSING = {"paper_repro.world.lidar", "paper_repro.sim", "paper_repro.sim.loop",
           "paper_repro.sim.perception", "paper_repro.world.local_map"}
"""What scans or flies: a figure draws what a result stored, and runs neither."""


def test_no_figure_scans_or_flies_again():
    """``plots`` draws the scans the controller was handed (``SimulationResult.scan``): none
    of its modules imports the LiDAR, the map or the closed loop."""
    for module, deps in INSIDE.items():
        if module.startswith("paper_repro.plots"):
            assert not deps & SENSING, f"{module} imports {sorted(deps & SENSING)}"


def test_the_cycle_finder_finds_a_cycle():
    """The check above can fail: a two-module loop is found, and so is a longer one."""
    assert _find_cycle({"a": {"b"}, "b": {"a"}}) == ["a", "b", "a"]
    assert _find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}) is not None
    assert _find_cycle({"a": {"b"}, "b": {"c"}, "c": set()}) is None


def test_subpackages_list_their_modules():
    """Each subpackage's ``__init__`` is its table of contents: its docstring names every
    module in it."""
    for init in ROOT.glob("*/__init__.py"):
        doc = ast.get_docstring(ast.parse(init.read_text())) or ""
        for module in init.parent.glob("[!_]*.py"):
            if module.name != "__init__.py":
                assert f"``{module.stem}``" in doc, f"{init.parent.name}: {module.stem}"


def test_no_module_is_longer_than_about_600_lines():
    lengths = {p.relative_to(ROOT).as_posix(): len(p.read_text().splitlines())
               for p in ROOT.rglob("*.py")}
    assert max(lengths.values()) <= 620, sorted(lengths.items(), key=lambda kv: -kv[1])[:3]


def _private_imports(folders=("paper_repro", "tests", "benchmarks")) -> list[str]:
    """``file: module.name`` for every private name (one underscore) imported from another
    module of the package; a private module itself (``_native``) may be imported."""
    top = ROOT.parent
    found = []
    for folder in folders:
        for path in sorted((top / folder).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text())):
                if not (isinstance(node, ast.ImportFrom) and node.module
                        and node.module.split(".")[0] == "paper_repro"):
                    continue
                base = top.joinpath(*node.module.split("."))
                for alias in node.names:
                    name = alias.name
                    is_module = (base / f"{name}.py").is_file() or (base / name).is_dir()
                    if name.startswith("_") and not name.startswith("__") and not is_module:
                        found.append(f"{path.relative_to(top)}: {node.module}.{name}")
    return found


def test_no_private_name_crosses_a_module():
    """A name with a leading underscore is its module's own: no other module, test or
    benchmark imports it (a test checks behaviour through public names)."""
    assert _private_imports() == []


def test_the_private_import_check_finds_one():
    probe = ROOT.parent / "tests" / "_probe_private_import.py"
    probe.write_text("from paper_repro.sim.loop import _vehicle\n")
    try:
        assert _private_imports(("tests",)) == [
            "tests/_probe_private_import.py: paper_repro.sim.loop._vehicle"]
    finally:
        probe.unlink()
