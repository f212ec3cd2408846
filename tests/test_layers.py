"""
The layers of lbscene: every module imports only modules of its own layer or of the layers
below it, and no import circle joins two modules, function-local imports included.

Every module of the packages in pyproject's ``package-dir`` is parsed with :mod:`ast`; each
``import``, ``from … import`` (relative ones resolved) and ``importlib.import_module("…")``
with a literal name, wherever it stands (module level, in a function, under ``if``), is an
edge.  A module's layer is given by the most specific prefix in :data:`LAYERS`.  Names built
at run time are not edges, on purpose: that is how the effect registry discovers its
plugins and the build finds the writers of the layers above it (both say so where they do
it).  The importing of a module's parent packages is not an edge either.

The checks are plain functions of an edge list (:func:`layer_violations`,
:func:`import_cycles`), so the tests at the end can feed them graphs that break the rules.
"""

from __future__ import annotations

import ast
import tomllib
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

#: The layers, lowest first: (name, module prefixes).  A module may import its own layer and
#: the layers before it.  Keep in step with CONTRIBUTING.md and engine/__init__.py.
LAYERS: list[tuple[str, tuple[str, ...]]] = [
    ("version", ("lbscene._version",)),
    ("schemas", ("lbscene.schemas",)),
    ("engine.files", ("lbscene.engine", "lbscene.engine.files")),
    ("engine.spectra", ("lbscene.engine.spectra",)),
    ("engine.colour", ("lbscene.engine.colour",)),
    ("engine.coatings", ("lbscene.engine.coatings",)),
    ("engine.light", ("lbscene.engine.light",)),
    ("engine.scene", ("lbscene.engine.scene",)),
    ("engine.truth", ("lbscene.engine.truth",)),
    ("engine.loop", ("lbscene.engine.loop",)),
    ("engine.visual", ("lbscene.engine.visual",)),
    ("engine.conformance", ("lbscene.engine.conformance",)),
    ("bakers", ("lbscene.bakers",)),
    ("runtimes", ("lbscene.runtimes",)),
    # the API, the command line and the JSON Schema export (`make schemas`, a command)
    ("app", ("lbscene", "lbscene.schemas.export")),
]

#: At most this many modules (``__init__`` aside) may sit at the top of engine/.
MAX_ENGINE_TOP_LEVEL = 12


@dataclass(frozen=True)
class Edge:
    """``src`` imports ``dst`` at ``path:line``."""

    src: str
    dst: str
    path: str
    line: int

    def where(self) -> str:
        return f"{self.path}:{self.line}"


# --------------------------------------------------------------------------- the modules

def package_roots() -> dict[str, Path]:
    """Package name → folder, from pyproject's ``package-dir`` (the data-only packages aside)."""
    mapping = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["package-dir"]
    return {pkg: REPO / folder for pkg, folder in mapping.items()
            if (REPO / folder / "__init__.py").is_file()}


def find_modules(roots: dict[str, Path]) -> dict[str, Path]:
    """Module name → file of every Python module under the package folders."""
    out: dict[str, Path] = {}
    for pkg, folder in roots.items():
        for f in sorted(folder.rglob("*.py")):
            parts = list(f.relative_to(folder).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join([pkg, *parts])] = f
    return out


def _known(name: str, modules) -> str | None:
    """The module ``name`` is, or the module it names an attribute of (longest known prefix)."""
    while name:
        if name in modules:
            return name
        name = name.rpartition(".")[0]
    return None


def imports_of(source: str, module: str, is_package: bool, modules) -> list[tuple[str, int]]:
    """``(imported lbscene module, line)`` of every import in ``source``, anywhere in it.

    ``module`` is the name of the module the source is (``is_package``: an ``__init__``), so
    that relative imports resolve; ``modules`` are the known module names.
    """
    out: list[tuple[str, int]] = []
    base = module.split(".") if is_package else module.split(".")[:-1]
    for node in ast.walk(ast.parse(source)):
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                pkg = base[: len(base) - (node.level - 1)]
                mod = ".".join(pkg + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            # `from pkg import sub` imports the module pkg.sub; `from mod import name` imports mod
            names = [f"{mod}.{a.name}" if f"{mod}.{a.name}" in modules else mod for a in node.names]
        elif (isinstance(node, ast.Call) and node.args and isinstance(node.args[0], ast.Constant)
              and isinstance(node.args[0].value, str)
              and (getattr(node.func, "attr", None) == "import_module"
                   or getattr(node.func, "id", None) == "import_module")):
            names = [node.args[0].value]
        for n in names:
            target = _known(n, modules)
            if target is not None and target != module:
                out.append((target, node.lineno))
    return out


def import_graph(roots: dict[str, Path] | None = None) -> tuple[dict[str, Path], list[Edge]]:
    """Every module and every import edge between lbscene's modules."""
    modules = find_modules(roots or package_roots())
    edges = []
    for name, path in modules.items():
        rel = path.relative_to(REPO).as_posix()
        for dst, line in imports_of(path.read_text(), name, path.name == "__init__.py", modules):
            edges.append(Edge(name, dst, rel, line))
    return modules, edges


# --------------------------------------------------------------------------- the checks

def layer_of(module: str, layers=LAYERS) -> int | None:
    """Index in ``layers`` of the most specific prefix that names ``module`` (None: no layer)."""
    best, best_len = None, -1
    for i, (_, prefixes) in enumerate(layers):
        for p in prefixes:
            if (module == p or module.startswith(p + ".")) and len(p) > best_len:
                best, best_len = i, len(p)
    return best


def layer_violations(edges, layers=LAYERS) -> list[str]:
    """One line per import of a module of a higher layer than the importer's."""
    out = []
    for e in edges:
        a, b = layer_of(e.src, layers), layer_of(e.dst, layers)
        if a is not None and b is not None and b > a:
            out.append(f"{e.where()}: {e.src} (layer {layers[a][0]}) imports {e.dst} "
                       f"(layer {layers[b][0]}, above it)")
    return out


def _strongly_connected(nodes, succ) -> list[list[str]]:
    """Tarjan's strongly connected components (iterative), those of more than one module."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    out = []
    counter = 0
    for root in sorted(nodes):
        if root in index:
            continue
        work = [(root, iter(sorted(succ.get(root, ()))))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on_stack.add(w)
                    work.append((w, iter(sorted(succ.get(w, ())))))
                elif w in on_stack:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on_stack.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
    return out


def _one_cycle(component: list[str], by_pair) -> list[Edge]:
    """A shortest import circle through the first module of a strongly connected component."""
    members = set(component)
    start = component[0]
    prev: dict[str, Edge] = {}
    frontier = [start]
    seen = {start}
    while frontier:
        nxt = []
        for v in frontier:
            for (a, b), e in sorted(by_pair.items()):
                if a != v or b not in members:
                    continue
                if b == start:
                    path = [e]
                    while path[0].src != start:
                        path.insert(0, prev[path[0].src])
                    return path
                if b not in seen:
                    seen.add(b)
                    prev[b] = e
                    nxt.append(b)
        frontier = nxt
    return []


def import_cycles(edges) -> list[str]:
    """One line per import circle: its modules in order, each import's file and line."""
    succ: dict[str, set[str]] = {}
    by_pair: dict[tuple[str, str], Edge] = {}
    for e in edges:
        succ.setdefault(e.src, set()).add(e.dst)
        by_pair.setdefault((e.src, e.dst), e)
    nodes = set(succ) | {e.dst for e in edges}
    out = []
    for comp in _strongly_connected(nodes, succ):
        cycle = _one_cycle(comp, by_pair)
        steps = " -> ".join(f"{e.src} ({e.where()})" for e in cycle)
        out.append(f"import circle among {len(comp)} modules {comp}: {steps} -> {cycle[0].src}")
    return out


# --------------------------------------------------------------------------- the repository

@pytest.fixture(scope="module")
def graph():
    return import_graph()


def test_every_module_has_a_layer(graph):
    modules, _ = graph
    assert len(modules) > 100                      # the packages were found
    assert [m for m in modules if layer_of(m) is None] == []


def test_every_engine_subpackage_is_a_layer_and_says_what_it_may_import():
    named = {p for _, prefixes in LAYERS for p in prefixes}
    for init in sorted((REPO / "engine").glob("*/__init__.py")):
        pkg = f"lbscene.engine.{init.parent.name}"
        assert pkg in named, f"{pkg}: add it to LAYERS (and to the map in CONTRIBUTING.md)"
        doc = ast.get_docstring(ast.parse(init.read_text())) or ""
        assert "May import" in doc, f"{init.relative_to(REPO)}: say what it owns and may import"


def test_engine_top_level_holds_few_modules():
    top = [f.name for f in (REPO / "engine").glob("*.py") if f.name != "__init__.py"]
    assert len(top) <= MAX_ENGINE_TOP_LEVEL, top


def test_no_module_imports_a_higher_layer(graph):
    _, edges = graph
    assert layer_violations(edges) == []


def test_no_import_circles(graph):
    _, edges = graph
    assert import_cycles(edges) == []


# --------------------------------------------------------------------------- the checks can fail

TOY_LAYERS = [("low", ("pkg.low",)), ("mid", ("pkg.mid",)), ("high", ("pkg.high",))]


def test_an_import_of_a_higher_layer_is_named_with_its_line():
    edges = [Edge("pkg.mid.a", "pkg.low.b", "mid/a.py", 3),        # down: fine
             Edge("pkg.low.b", "pkg.high.c", "low/b.py", 42)]      # up: refused
    assert layer_violations(edges, TOY_LAYERS) == [
        "low/b.py:42: pkg.low.b (layer low) imports pkg.high.c (layer high, above it)"]


def test_the_most_specific_prefix_names_the_layer():
    layers = [("low", ("pkg",)), ("high", ("pkg.tool",))]
    assert layer_of("pkg.core", layers) == 0
    assert layer_of("pkg.tool.export", layers) == 1
    assert layer_of("other", layers) is None
    assert layer_violations([Edge("pkg.core", "pkg.tool", "core.py", 7)], layers) != []
    assert layer_violations([Edge("pkg.tool", "pkg.core", "tool.py", 7)], layers) == []


def test_an_import_circle_is_named_with_its_modules_and_lines():
    edges = [Edge("pkg.low.a", "pkg.low.b", "a.py", 10),
             Edge("pkg.low.b", "pkg.low.c", "b.py", 20),
             Edge("pkg.low.c", "pkg.low.a", "c.py", 30),          # closes a → b → c → a
             Edge("pkg.low.c", "pkg.low.d", "c.py", 31)]          # d is outside the circle
    (msg,) = import_cycles(edges)
    assert "['pkg.low.a', 'pkg.low.b', 'pkg.low.c']" in msg
    assert ("pkg.low.a (a.py:10) -> pkg.low.b (b.py:20) -> pkg.low.c (c.py:30) -> pkg.low.a"
            in msg)
    assert import_cycles([e for e in edges if e.path != "c.py" or e.line != 30]) == []


def test_two_modules_importing_each_other_are_a_circle():
    edges = [Edge("m.x", "m.y", "x.py", 1), Edge("m.y", "m.x", "y.py", 2)]
    assert len(import_cycles(edges)) == 1


def test_function_local_relative_and_literal_dynamic_imports_are_edges():
    modules = {"pkg", "pkg.sub", "pkg.sub.a", "pkg.sub.b", "pkg.c", "pkg.d", "pkg.e"}
    source = (
        "import os\n"
        "from . import b\n"                             # pkg.sub.b (a module of the package)
        "def f():\n"
        "    from ..c import thing\n"                   # pkg.c, inside a function
        "    if True:\n"
        "        import pkg.d as d\n"                   # pkg.d, nested deeper
        "    importlib.import_module('pkg.e')\n"        # a literal dynamic import
        "    importlib.import_module(name)\n"           # a name built at run time: no edge
    )
    got = imports_of(source, "pkg.sub.a", False, modules)
    assert sorted(got) == [("pkg.c", 4), ("pkg.d", 6), ("pkg.e", 7), ("pkg.sub.b", 2)]
