"""The package's shape, read from its code: no import cycles (imports inside functions and
under TYPE_CHECKING count: they are cycles all the same, only hidden), no module takes
another's private name, and the CLI reaches the engine only through public names."""

from __future__ import annotations

import ast
from pathlib import Path

import dkreason

ROOT = Path(dkreason.__file__).parent


def _modules() -> dict[str, Path]:
    out = {}
    for path in sorted(ROOT.rglob("*.py")):
        parts = ["dkreason", *path.relative_to(ROOT).with_suffix("").parts]
        if parts[-1] == "__init__":
            parts.pop()
        out[".".join(parts)] = path
    return out


MODULES = _modules()


def _imports(name: str, path: Path) -> list[tuple[str, str, int]]:
    """(module imported, name taken from it or '', line) for every dkreason import."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found += [(a.name, "", node.lineno) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*up, *([base] if base else [])])
            for alias in node.names:
                module = f"{base}.{alias.name}"  # `from pkg import module`
                found.append(
                    (module, "", node.lineno)
                    if module in MODULES
                    else (base, alias.name, node.lineno)
                )
    return [(m, n, line) for m, n, line in found if m.split(".")[0] == "dkreason"]


def _graph() -> dict[str, set[str]]:
    return {
        name: {m for m, _, _ in _imports(name, path) if m in MODULES and m != name}
        for name, path in MODULES.items()
    }


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while (w := stack.pop()) != v:
                component.append(w)
            component.append(v)
            if len(component) > 1:
                out.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_the_graph_is_read_from_every_kind_of_import() -> None:
    graph = _graph()
    assert "dkreason.manager" in graph["dkreason.cli.knowledge"]  # at the top
    assert "dkreason.stream.binding" in graph["dkreason.manager"]  # inside a function
    assert "dkreason.stream.policy" in graph["dkreason.manager"]  # under TYPE_CHECKING too
    assert "dkreason.inputs.xmlsafe" in graph["dkreason.parse.owl"]  # `from ..inputs import x`
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_module_is_in_an_import_cycle() -> None:
    assert _cycles(_graph()) == []


def test_no_module_takes_another_modules_private_name() -> None:
    private = [
        f"{MODULES[name].relative_to(ROOT)}:{line}: {module}.{taken}"
        for name in MODULES
        for module, taken, line in _imports(name, MODULES[name])
        if taken.startswith("_") and not taken.startswith("__") and module != name
    ]
    assert private == []


def test_the_cli_imports_only_the_facade_and_public_modules() -> None:
    cli = [name for name in MODULES if name.startswith("dkreason.cli")]
    reached = {m for name in cli for m, _, _ in _imports(name, MODULES[name])}
    assert "dkreason.manager" in reached
    assert not [m for m in reached if any(p.startswith("_") for p in m.split("."))]


def test_the_command_line_is_declared_without_loading_an_engine() -> None:
    """`dkreason --help` imports the parser and what it imports, nothing heavy: a command's
    module (and with it the knowledge base, the readers, the progressor) loads when it runs."""
    graph, seen, todo = _graph(), set(), ["dkreason.cli", "dkreason.cli.parser"]
    while todo:
        name = todo.pop()
        if name not in seen:
            seen.add(name)
            todo += graph[name]
    heavy = {"dkreason.manager", "dkreason.monitor", "dkreason.kb", "dkreason.parse.formula"}
    assert not seen & heavy
