"""The package's import graph: no cycles, and the leaves import no other layer.

Every ``import`` / ``from ... import`` of a damjax module counts, at module level or inside
a function (a deferred import is still a dependency). ``from damjax.x import y`` is an edge
to ``damjax.x.y`` when that is a module, else to ``damjax.x``; importing a submodule does
not count as importing its package's ``__init__``. The deprecation shims of the old paths
(``damjax.config``, ``damjax.scenarios``, ...) forward by name at run time and import no
damjax module.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import damjax

ROOT = Path(damjax.__file__).parent

# layer 0: they import nothing from damjax but each other (and fields reads terrain's maps)
LEAVES = ("damjax._version", "damjax.constants", "damjax.materials", "damjax.terrain")
LEAVES += ("damjax.fields", "damjax.theory", "damjax.io")


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


@pytest.mark.parametrize("leaf", LEAVES)
def test_leaves_import_only_leaves(leaf):
    graph = _graph()
    inside = [m for m in graph if m == leaf or m.startswith(leaf + ".")]
    assert inside
    for module in inside:
        for target in graph[module]:
            assert any(target == x or target.startswith(x + ".") for x in LEAVES), (
                f"{module} imports {target}, which is not a leaf"
            )
