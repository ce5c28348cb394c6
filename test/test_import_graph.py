"""The project's own import graph, read from the source: no cycle anywhere, and the layers point one way;
and tests that use only public names (the AST scan at the end).

Every import of a ``flow_node`` module counts, wherever it stands: at the top, inside a function (a "lazy"
import only hides a cycle until that function runs) or under ``if TYPE_CHECKING`` (a type dependency is a
dependency). ``from . import x`` and ``from .pkg import name`` resolve to the submodule when ``x`` / ``name``
is one, else to the package. Importing ``a.b.c`` also runs ``a/__init__.py`` and ``a/b/__init__.py``; those
implicit edges are Python's, not the code's, and are left out (docs/design.md, "Layers").
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = "flow_node"
Graph = dict[str, set[str]]


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imported(node: ast.Import | ast.ImportFrom, module: str, is_package: bool, known: set[str]) -> set[str]:
    """The project modules one import statement of ``module`` names."""
    if isinstance(node, ast.Import):
        return {a.name for a in node.names if a.name.split(".")[0] == PACKAGE}
    if node.level:
        base = module.split(".") if is_package else module.split(".")[:-1]
        base = base[:len(base) - node.level + 1]
        target = ".".join(base + ([node.module] if node.module else []))
    else:
        target = node.module or ""
    if target.split(".")[0] != PACKAGE:
        return set()
    return {f"{target}.{a.name}" if f"{target}.{a.name}" in known else target for a in node.names}


def import_graph() -> Graph:
    """module -> the project modules it imports (itself excluded)."""
    files = {module_name(p): p for p in sorted((ROOT / PACKAGE).rglob("*.py"))}
    known = set(files)
    graph: Graph = {}
    for module, path in files.items():
        tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
        deps: set[str] = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.Import | ast.ImportFrom):
                deps |= imported(node, module, path.name == "__init__.py", known)
        unknown = deps - known
        assert not unknown, f"{module} imports {sorted(unknown)}, which are not modules of the project"
        graph[module] = deps - {module}
    return graph


def find_cycle(graph: Graph) -> list[str] | None:
    """One cycle as [a, b, ..., a], or None: iterative depth-first search (white/grey/black)."""
    state: dict[str, int] = {}  # 1 on the current path, 2 done
    for root in sorted(graph):
        if state.get(root):
            continue
        path, todo = [root], [iter(sorted(graph[root]))]
        state[root] = 1
        while todo:
            nxt = next(todo[-1], None)
            if nxt is None:
                state[path.pop()] = 2
                todo.pop()
            elif state.get(nxt) == 1:
                return path[path.index(nxt):] + [nxt]
            elif not state.get(nxt):
                state[nxt] = 1
                path.append(nxt)
                todo.append(iter(sorted(graph[nxt])))
    return None


def layer(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


@pytest.fixture(scope="module")
def graph() -> Graph:
    return import_graph()


def test_the_graph_is_read_from_the_source(graph: Graph) -> None:
    """The reader finds what is there: top-level, relative, lazy (in a function) and package imports."""
    assert "flow_node.core.config" in graph["flow_node.core.api"]  # from .config import ...
    assert "flow_node.core.fusion" in graph["flow_node.core.confidence"]
    assert "flow_node.bag.batch_report" in graph["flow_node.bag.batch"]  # imported inside run_batch
    assert "flow_node.core" in graph["flow_node"]  # from .core import ...
    assert "flow_node.cli.common" in graph["flow_node.bag.cli"]  # from ..cli.common import ...


def test_there_is_no_import_cycle(graph: Graph) -> None:
    cycle = find_cycle(graph)
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])


def test_a_cycle_is_found_and_shown() -> None:
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b", "c"}, "b": {"c"}, "c": set()}) is None


def test_the_engine_and_the_pipeline_import_nothing_above_them(graph: Graph) -> None:
    """core/ imports only core/; pipeline/ only core/ and pipeline/ (docs/design.md, "Layers")."""
    allowed = {"core": {"core"}, "pipeline": {"core", "pipeline"}}
    wrong = [(m, d) for m, deps in graph.items() if layer(m) in allowed
             for d in deps if layer(d) not in allowed[layer(m)]]
    assert not wrong, f"imports against the layers: {wrong}"


def test_the_node_and_the_bag_tools_do_not_import_each_other(graph: Graph) -> None:
    """ros/ (rclpy) and bag/ (rosbags) sit side by side on the pipeline: neither imports the other. What both
    need lives below them (flow_node/middleware.py: the Fast DDS profile the node and `flow_bag play` apply)."""
    apart = {"ros": "bag", "bag": "ros"}
    wrong = [(m, d) for m, deps in graph.items() if layer(m) in apart for d in deps if layer(d) == apart[layer(m)]]
    assert not wrong, f"imports between ros/ and bag/: {wrong}"
    assert all("flow_node.middleware" in graph[m] for m in ("flow_node.bag.cli", "flow_node.ros.node"))


# namedtuple's public API is spelled with a leading underscore
NAMEDTUPLE_API = frozenset({"_replace", "_asdict", "_fields", "_make", "_field_defaults"})
ATTRIBUTE_CALLS = frozenset({"getattr", "setattr", "hasattr", "delattr"})


def private_accesses(source: str) -> list[tuple[int, str]]:
    """(line, text) of every access to another object's private name in ``source``: ``x._name`` where ``x``
    is not ``self``/``cls`` (dunders and namedtuple's API aside), and ``getattr(x, "_name")`` and its kin,
    ``monkeypatch.setattr(x, "_name", ...)`` included."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Attribute):
            name, owner = node.attr, node.value
            mine = isinstance(owner, ast.Name) and owner.id in ("self", "cls")
            if name.startswith("_") and not name.startswith("__") and name not in NAMEDTUPLE_API and not mine:
                found.append((node.lineno, ast.unparse(node)))
        elif isinstance(node, ast.Call) and len(node.args) >= 2:
            fn = node.func
            called = fn.id if isinstance(fn, ast.Name) else fn.attr if isinstance(fn, ast.Attribute) else ""
            key = node.args[1]
            if (called in ATTRIBUTE_CALLS and isinstance(key, ast.Constant) and isinstance(key.value, str)
                    and key.value.startswith("_") and not key.value.startswith("__")):
                found.append((node.lineno, ast.unparse(node)))
    return found


def test_the_private_access_scan_finds_what_it_should() -> None:
    source = ("h.node._stats.totals\nself._x = 1\nt._replace(a=1)\nx.__class__\n"
              "monkeypatch.setattr(messages, '_FLAG', True)\ngetattr(est, 'backend')\n")
    assert sorted(private_accesses(source)) == [(1, "h.node._stats"),
                                                (5, "monkeypatch.setattr(messages, '_FLAG', True)")]


def test_tests_use_only_public_names() -> None:
    """No test reaches into a private name of flow_node code (or anyone's): what a test needs to know, the
    code offers as a public, read-only accessor (FlowNode.state(), FlowNode.stats, ...), or the test
    observes it through behaviour."""
    wrong = [f"{path.name}:{line}: {text}" for path in sorted((ROOT / "test").glob("*.py"))
             for line, text in private_accesses(path.read_text(encoding="utf-8"))]
    assert not wrong, "private names used by tests:\n" + "\n".join(wrong)
