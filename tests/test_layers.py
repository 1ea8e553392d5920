"""brdfcl's modules import one another only downward: no import cycle among them, counting the
imports written inside functions too (a function-local import may keep a heavy optional
dependency such as Dask or matplotlib off ``import brdfcl.x``, never hide a cycle).

The edges are read from the source with ``ast`` (nothing is imported): every ``from .x import``,
``from ..x import``, ``from . import x``, ``import brdfcl.x`` and ``from brdfcl.x import``, at module
level or in a function.  ``from . import name`` is an edge to the submodule ``name`` when there is
one, else to the package's ``__init__``.  Run this file as a script to print the edges.
"""
import ast
import sys
from pathlib import Path

import brdfcl

PACKAGE = Path(brdfcl.__file__).resolve().parent
ROOT = PACKAGE.name                         # "brdfcl"


def modules():
    """{dotted name: path} of every module of the package (a package is its __init__.py)."""
    found = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = (ROOT,) + path.relative_to(PACKAGE).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        found[".".join(parts)] = path
    return found


def _local_nodes(tree):
    """ids of the import nodes that sit inside a function (or a class body)."""
    local = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda, ast.ClassDef)):
            local.update(id(n) for n in ast.walk(node) if isinstance(n, (ast.Import, ast.ImportFrom)))
    return local


def imports(name, path, known):
    """[(target module, line, local)] of one module's imports of brdfcl modules."""
    tree = ast.parse(path.read_text(), str(path))
    local = _local_nodes(tree)
    is_package = path.name == "__init__.py"
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names if a.name == ROOT or a.name.startswith(ROOT + ".")]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".")
                base = base[:len(base) - node.level + is_package]
                stem = ".".join(base + ([node.module] if node.module else []))
            elif node.module and (node.module == ROOT or node.module.startswith(ROOT + ".")):
                stem = node.module
            else:
                continue
            # "from . import report" imports the submodule; "from . import __version__" the package
            targets = [f"{stem}.{a.name}" if f"{stem}.{a.name}" in known else stem for a in node.names]
        else:
            continue
        for t in dict.fromkeys(targets):
            while t not in known and "." in t:      # "import brdfcl.x.y" of a name defined in x
                t = t.rsplit(".", 1)[0]
            if t != name:
                found.append((t, node.lineno, id(node) in local))
    return found


def import_graph():
    """{module: {imported module: [(line, local)]}} over every brdfcl module."""
    known = modules()
    graph = {m: {} for m in known}
    for m, path in known.items():
        for t, line, local in imports(m, path, known):
            graph[m].setdefault(t, []).append((line, local))
    return graph


def cycles(graph):
    """The strongly connected components of more than one module (Tarjan), each sorted."""
    index, low, stack, on_stack, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
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

    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, 10 * len(graph) + 100))
    try:
        for v in sorted(graph):
            if v not in index:
                visit(v)
    finally:
        sys.setrecursionlimit(limit)
    return out


def loops(graph, component):
    """The shortest import loop through each module of a cycle, each once: ``a -> b -> a``."""
    inside, seen, out = set(component), set(), []
    for start in component:
        paths, queue = {start: [start]}, [start]
        while queue:
            a = queue.pop(0)
            for b in sorted(graph[a]):
                if b == start:
                    loop = paths[a] + [start]
                    key = frozenset(zip(loop, loop[1:]))
                    if key not in seen:
                        seen.add(key)
                        out.append(loop)
                    queue = []
                    break
                if b in inside and b not in paths:
                    paths[b] = paths[a] + [b]
                    queue.append(b)
    return out


def describe(graph, component):
    """Each loop of one cycle, then its edges, one a line: ``a -> b (line 12 in a function)``."""
    lines = ["  loop: " + " -> ".join(loop) for loop in loops(graph, component)]
    inside = set(component)
    for a in component:
        for b, where in sorted(graph[a].items()):
            if b in inside:
                at = ", ".join(f"line {n}{' in a function' if local else ''}" for n, local in where)
                lines.append(f"  {a} -> {b} ({at})")
    return "\n".join(lines)


def test_the_walker_sees_the_imports():
    """The edges the cycle test relies on are found, at module level and in functions."""
    graph = import_graph()
    assert len(graph) > 30
    assert (False in [local for _, local in graph["brdfcl.app.run"]["brdfcl.app.analyze"]])
    assert all(local for _, local in graph["brdfcl.report.writers.pages"]["brdfcl.report.view.pages"])
    assert "brdfcl.model.lobes.cells" in graph["brdfcl.device.cellsets"]
    assert "brdfcl.model.compose" in graph["brdfcl.report.view.pages"]
    assert "brdfcl.report.writers" in graph["brdfcl.app.runner"]


def test_no_import_cycle():
    graph = import_graph()
    found = cycles(graph)
    assert not found, "import cycles among brdfcl's modules (each runs back up a layer):\n" + \
        "\n".join(describe(graph, c) for c in found)


def test_run_analyze_cluster_import_downward():
    """fit_all's module imports the analysis and the cluster job; neither, nor the job runner
    they share (brdfcl.app.runner), imports it back."""
    graph = import_graph()
    assert {"brdfcl.app.analyze", "brdfcl.app.cluster"} <= set(graph["brdfcl.app.run"])
    for m in ("brdfcl.app.analyze", "brdfcl.app.cluster", "brdfcl.data.inputs", "brdfcl.app.runner"):
        assert "brdfcl.app.run" not in graph[m], m


LAYERS = ("_version", "_words", "_lazy", "_cache", "data", "model", "kernels", "device", "optim", "analysis",
          "report", "app")
"""brdfcl's layer folders, bottom first: a module imports only from its own layer or lower ones."""


def layer(module):
    """The index in LAYERS of a module's folder (the package's ``__init__``, the facade: None)."""
    parts = module.split(".")
    return LAYERS.index(parts[1]) if len(parts) > 1 else None


def test_every_module_sits_in_a_layer():
    assert all(m == ROOT or m.split(".")[1] in LAYERS for m in modules()), \
        [m for m in modules() if m != ROOT and m.split(".")[1] not in LAYERS]


def test_imports_run_down_the_layers():
    """No import runs up a layer, at module level or in a function."""
    graph = import_graph()
    up = [f"{a} -> {b} (line {where[0][0]})" for a, targets in graph.items() for b, where in targets.items()
          if layer(a) is not None and layer(b) is not None and layer(b) > layer(a)]
    assert not up, "imports running up a layer (" + " < ".join(LAYERS) + "):\n" + "\n".join(up)


if __name__ == "__main__":
    g = import_graph()
    for m in sorted(g):
        for t, where in sorted(g[m].items()):
            print(m, "->", t, " ".join(f"{n}{'(local)' if loc else ''}" for n, loc in where))
    for c in cycles(g):
        print("CYCLE:\n" + describe(g, c))
