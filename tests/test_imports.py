"""The package's import graph: no cycles (also none hidden by imports inside functions),
and every module imports on its own, first, in a fresh interpreter state."""

import ast
import subprocess
import sys
from pathlib import Path

import qdrefine

PACKAGE = Path(qdrefine.__file__).parent


def modules() -> dict[str, Path]:
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _type_checking_only(tree: ast.AST) -> set[int]:
    """Line numbers of imports under ``if TYPE_CHECKING:`` (never run)."""
    lines = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for inner in node.body:
                lines.update(range(inner.lineno, (inner.end_lineno or inner.lineno) + 1))
    return lines


def import_graph() -> dict[str, set[str]]:
    """Module -> the package modules it imports when run, at module level or inside
    functions (the root package, which re-exports the API, is left out as a source)."""
    mods = modules()
    graph = {}
    for name, path in mods.items():
        tree = ast.parse(path.read_text())
        skip = _type_checking_only(tree)
        package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
        targets = set()
        for node in ast.walk(tree):
            if getattr(node, "lineno", None) in skip:
                continue
            if isinstance(node, ast.Import):
                targets.update(a.name for a in node.names)
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package.split(".")
                    base = base[: len(base) - (node.level - 1)]
                    base = ".".join(base + ([node.module] if node.module else []))
                else:
                    base = node.module or ""
                for alias in node.names:
                    full = f"{base}.{alias.name}"
                    targets.add(full if full in mods else base)
        graph[name] = {t for t in targets if t in mods and t != name}
    graph["qdrefine"] = set()
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_import_graph_is_acyclic():
    graph = import_graph()
    assert len(graph) > 50 and "qdrefine.adaptive.rounds" in graph["qdrefine.adaptive.step"]
    assert cycles(graph) == []


def test_the_cycle_finder_finds_cycles():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_every_module_imports_alone():
    """Each module imported on its own (one interpreter for all, so third-party imports are
    paid once). Importing any submodule runs the package's ``__init__`` first, which
    imports the core: so the root package is imported first, alone, and then each of the
    other modules with every module but the core forgotten before it."""
    names = sorted(n for n in modules()  # ``__main__`` modules run when imported
                   if not n.endswith("__main__"))
    code = (
        "import importlib, sys\n"
        "import qdrefine\n"
        "core = {k for k in sys.modules if k.startswith('qdrefine.')}\n"
        "def forget():  # all but the root package and what it imports\n"
        "    for key in [k for k in sys.modules if k.startswith('qdrefine.') and k not in core]:\n"
        "        del sys.modules[key]\n"
        f"failed, tried = [], 0\nfor name in {names!r}:\n"
        "    if name in core:\n        continue\n"
        "    forget()\n    tried += 1\n"
        "    try:\n        importlib.import_module(name)\n"
        "    except Exception as exc:\n        failed.append(f'{name}: {exc!r}')\n"
        "print(len(core), tried)\nprint('\\n'.join(failed))\n"
    )
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    counts, _, failed = run.stdout.partition("\n")
    core, tried = map(int, counts.split())
    assert core + tried == len(names), (core, tried, len(names))
    assert tried > 10 and failed.strip() == ""


def layers() -> list[list[str]]:
    """The layer table of ``docs/architecture.md``: per row, its modules as dotted names."""
    text = (Path(__file__).parents[1] / "docs" / "architecture.md").read_text()
    table = text.split("## Layers", 1)[1].split("\n\n", 2)[1]
    out = []
    for line in table.splitlines()[2:]:
        cells = line.split("|")
        names = [n.strip().strip("`").removesuffix(".py").rstrip("/").replace("/", ".")
                 for n in cells[2].split(",")]
        out.append(["qdrefine." + n for n in names])
    return out


ROOT = ("qdrefine", "qdrefine.__main__")  # the API's re-exports and ``python -m``


def test_layers_of_the_architecture_guide_hold():
    """Every module sits in a row of the table in ``docs/architecture.md`` and imports only
    from its own row and the rows above (the most specific entry wins: ``adaptive/bounds``
    is a study, the rest of ``adaptive/`` an algorithm)."""
    rows = layers()
    assert len(rows) >= 8

    def row(module):
        best, at = -1, None
        for i, names in enumerate(rows):
            for n in names:
                if (module == n or module.startswith(n + ".")) and len(n) > best:
                    best, at = len(n), i
        return at

    graph = import_graph()
    unplaced = [m for m in graph if row(m) is None and m not in ROOT]
    assert unplaced == []
    upward = [(a, b) for a, targets in graph.items() for b in targets
              if a not in ROOT and b not in ROOT and row(b) > row(a)]
    assert upward == []


def test_long_modules_say_why_they_are_one_concern():
    """A source module over 400 lines is one concern and says so (``One concern`` in its
    docstring, with the reason); every other module stays under 400 lines."""
    long = {}
    for name, path in modules().items():
        text = path.read_text(encoding="utf-8")
        if text.count("\n") > 400:
            long[name] = "One concern" in (ast.get_docstring(ast.parse(text)) or "")
    assert all(long.values()), [name for name, ok in long.items() if not ok]
