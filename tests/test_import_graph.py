"""The package's import graph: no cycles, and the layer order of CONTRIBUTING.md (a
module imports only from its own layer or below), read from its table.

Every ``import`` / ``from ... import`` of a damjax module counts, at module level or inside
a function (a deferred import is still a dependency). ``from damjax.x import y`` is an edge
to ``damjax.x.y`` when that is a module, else to ``damjax.x``; importing a submodule does
not count as importing its package's ``__init__``.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import damjax

ROOT = Path(damjax.__file__).parent
CONTRIBUTING = ROOT.parent / "CONTRIBUTING.md"
# above every layer: the package's __init__ (the public API) and ``python -m damjax``
TOP = ("damjax", "damjax.__main__")


def _module_name(path: Path) -> str:
    parts = path.relative_to(ROOT.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted(ROOT.rglob("*.py"))}


def _imports(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """damjax modules that module ``name`` (file ``path``) imports, anywhere in it."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative import
                anchor = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                base = ".".join(anchor + ([base] if base else []))
            targets = [
                f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base for a in node.names
            ]
        else:
            continue
        for t in targets:
            while t and t not in modules:  # `import damjax.core.step as s` and the like
                t = t.rpartition(".")[0]
            if t.startswith("damjax") and t != name:
                out.add(t)
    return out


def _graph() -> dict[str, set[str]]:
    modules = _modules()
    return {name: _imports(name, path, modules) for name, path in modules.items()}


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle of the graph as a list of modules (first == last), or None."""
    state: dict[str, int] = {}  # 1: on the stack, 2: done
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt) :] + [nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return None


def test_the_import_graph_is_read():
    graph = _graph()
    assert "damjax.pst" in graph["damjax"]  # `from damjax.pst import ...`
    assert "damjax.core.model" in graph["damjax.pst"]
    assert "damjax.fields.maps" in graph["damjax.fields.grf"]
    assert "damjax.theory" in graph["damjax.validation"]
    # a function-level import counts
    assert "damjax.terrain" in graph["damjax.fields.maps"]


def test_the_cycle_finder_finds_a_cycle():
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b"}, "b": set(), "c": {"a"}}) is None


def test_no_import_cycles():
    cycle = _cycle(_graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])


def layers(text: str, modules: set[str]) -> dict[str, tuple[int, str]]:
    """Module (or package) -> (its layer's rank, 0 the bottom; its name), from the table of
    CONTRIBUTING.md: each row names its modules in backticks (`params`, `core/`,
    `core/model.py`); backticked words that name no module (classes, functions) are
    passed over."""
    section = text[text.index("## Layers") :]
    rows = [line for line in section.splitlines()[1:] if line.startswith("|")]
    out: dict[str, tuple[int, str]] = {}
    for rank, row in enumerate(rows[2:]):  # past the header and the |---| line
        layer, column = row.split("|")[1:3]
        for word in re.findall(r"`([^`]+)`", column):
            name = "damjax." + word.removesuffix("/").removesuffix(".py").replace("/", ".")
            if name in modules or any(m.startswith(name + ".") for m in modules):
                out[name] = (rank, layer.strip())
    return out


def layer_of(module: str, table: dict[str, tuple[int, str]]) -> int | None:
    """The rank of a module: that of the longest entry of the table it is or lies in."""
    hits = [n for n in table if module == n or module.startswith(n + ".")]
    return table[max(hits, key=len)][0] if hits else None


def upward(graph: dict[str, set[str]], table: dict[str, tuple[int, str]]) -> list[str]:
    """Each import of a module from a layer above its own, as a line."""
    names = dict(table.values())
    out = []
    for module in sorted(graph):
        if module in TOP:
            continue
        mine = layer_of(module, table)
        for target in sorted(graph[module]):
            theirs = layer_of(target, table)
            if mine is not None and theirs is not None and theirs > mine:
                out.append(
                    f"{module} ({names[mine]}) imports {target} ({names[theirs]}), a layer "
                    "above its own"
                )
    return out


def _table() -> dict[str, tuple[int, str]]:
    return layers(CONTRIBUTING.read_text(encoding="utf-8"), set(_modules()))


def test_the_layer_table_is_read_and_places_every_module():
    table = _table()
    assert layer_of("damjax.constants", table) == 0
    assert layer_of("damjax.params", table) == layer_of("damjax.validation", table) == 1
    assert layer_of("damjax.core.model", table) == 2
    assert layer_of("damjax.pst", table) == layer_of("damjax.slope.simulation", table) == 4
    assert layer_of("damjax.scenario.schema", table) == layer_of("damjax.cli", table) == 5
    unplaced = [m for m in _modules() if m not in TOP and layer_of(m, table) is None]
    assert not unplaced, f"modules in no layer of CONTRIBUTING.md: {unplaced}"


def test_the_layer_check_finds_an_upward_import():
    table = {
        "damjax.params": (1, "parameters"),
        "damjax.core": (2, "core"),
        "damjax.cli": (5, "workflows"),
    }
    graph = {"damjax.core.model": {"damjax.params"}, "damjax.params": {"damjax.cli"}}
    assert upward(graph, table) == [
        "damjax.params (parameters) imports damjax.cli (workflows), a layer above its own"
    ]


def test_no_module_imports_from_a_layer_above_its_own():
    lines = upward(_graph(), _table())
    assert not lines, "\n".join(lines)


def test_the_core_imports_nothing_from_validation():
    """Values are checked at the edge (`damjax.pst.prepare`, ...); the core reads the
    declarations of `damjax.params` for its run-time guards, never the checks."""
    graph = _graph()
    core = [m for m in graph if m.startswith("damjax.core")]
    assert core
    assert not [(m, t) for m in core for t in graph[m] if t == "damjax.validation"]


def test_submodules_the_docs_name_are_attributes_after_import_damjax():
    """`damjax.distributed.sweep`, `damjax.export.gis.export_gis`, ... work after a plain
    `import damjax` (a fresh interpreter: nothing else imported them before)."""
    import subprocess
    import sys

    names = [
        "damjax.distributed.sweep",
        "damjax.release_area.read_release_area",
        "damjax.export.gis.export_gis",
        "damjax.export.avaframe.export_avaframe",
        "damjax.ensemble.run",
        "damjax.snow_profiles",
    ]
    code = "import damjax\n" + "\n".join(f"assert {n} is not None" for n in names)
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-2000:]
