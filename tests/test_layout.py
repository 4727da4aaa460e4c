"""The package's layout: its modules import one way (no cycles), and none grows past a size one reads in a sitting.

The import graph is read from the source with `ast`, not by importing: every `import` and `from ... import` of an
hvs_sim module counts, wherever it stands (module level, inside a function, under TYPE_CHECKING). `from a.b import c`
is an edge to the module a.b.c when there is one, else to a.b. Importing a submodule also runs its parents'
`__init__`; that implicit step is not an edge, so a package's `__init__` may gather its own submodules, but a
submodule that imports its package back (`from hvs_sim.cli import x` inside hvs_sim.cli.y) is a cycle.
"""

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "hvs_sim"
MAX_LINES = 500
# modules allowed past MAX_LINES, each with why; the list only shrinks
LONG_MODULES: dict[str, str] = {}


def _module_name(path: Path) -> str:
    rel = path.relative_to(PACKAGE.parent).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
    return ".".join(parts)


def _imports(path: Path, name: str, modules: set[str]) -> set[str]:
    """The hvs_sim modules `path` (module `name`) imports, anywhere in it."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:  # relative: from the package, one level up per extra dot
                parent = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*parent, base] if base else parent)
            for alias in node.names:
                full = f"{base}.{alias.name}"
                out.add(full if full in modules else base)
        elif isinstance(node, ast.Import):
            out |= {alias.name for alias in node.names}
    return {m for m in out if m in modules} - {name}


def _graph() -> dict[str, set[str]]:
    paths = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    return {m: _imports(p, m, set(paths)) for m, p in paths.items()}


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """One cycle per strongly connected component of more than one module (Tarjan's algorithm)."""
    index, low, stack, on_stack, found = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
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
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_the_graph_is_read():
    graph = _graph()
    assert "hvs_sim.cli.misc" in graph["hvs_sim.cli"]
    assert "hvs_sim.errors" in graph["hvs_sim.cli"]  # from hvs_sim.errors import HvsError
    assert "hvs_sim.outputs" in graph["hvs_sim.cli"]  # from hvs_sim import outputs
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]


def test_no_import_cycles():
    cycles = _cycles(_graph())
    assert not cycles, f"modules that import each other (directly or through others): {cycles}"


def test_no_module_is_too_long():
    lengths = {p.relative_to(PACKAGE.parent).as_posix(): len(p.read_text().splitlines()) for p in PACKAGE.rglob("*.py")}
    long = {p: n for p, n in lengths.items() if n > MAX_LINES and p not in LONG_MODULES}
    assert not long, f"modules over {MAX_LINES} lines: {long}; split them along what their parts are for"
    assert set(LONG_MODULES) <= set(lengths), "LONG_MODULES names a module that is gone: take it off the list"


def test_every_public_name_resolves_and_import_stays_light():
    import subprocess
    import sys

    import hvs_sim

    eager = {"ConfigError", "HvsError", "InputError", "OutputError", "RenderError", "StateError", "WeightsError",
             "__version__"}
    assert set(hvs_sim.__all__) == eager | set(hvs_sim._LAZY) and len(hvs_sim.__all__) == len(set(hvs_sim.__all__))
    assert set(hvs_sim.__all__) <= set(dir(hvs_sim))
    # a fresh interpreter: importing the package loads none of the lazy names' modules (nor MuJoCo or torch)
    heavy = sorted({*hvs_sim._LAZY.values(), "mujoco", "torch"})
    code = f"import sys, hvs_sim; print([m for m in {heavy!r} if m in sys.modules])"
    assert subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip() == "[]"
    for name in hvs_sim.__all__:
        assert getattr(hvs_sim, name) is not None, name
    from hvs_sim import ServoLoop, register_tracker  # from-imports go through __getattr__ too

    assert ServoLoop.__module__ == "hvs_sim.servo.loop" and register_tracker.__module__ == "hvs_sim.plugins"


# Sample data reserved for independent evaluation: never imported by the package, its experiments or its tests.
RESERVED_MODULES = ("skimage", "matplotlib.cbook")  # scikit-image's photographs; matplotlib's get_sample_data
RESERVED_FILES = ("vtest.avi",)  # OpenCV's sample clip


def _reserved_uses(path: Path) -> list[str]:
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        names = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and not node.level:
            names = [node.module or ""]
        elif isinstance(node, ast.Constant) and isinstance(node.value, str):
            found += [f"'{f}'" for f in RESERVED_FILES if f in node.value]
        found += [n for n in names if any(n == m or n.startswith(m + ".") for m in RESERVED_MODULES)]
    return found


def test_reserved_sample_data_is_never_used(tmp_path):
    root = PACKAGE.parent
    this = Path(__file__).resolve()
    uses = {p.relative_to(root).as_posix(): u for d in ("hvs_sim", "experiments", "tests")
            for p in sorted((root / d).rglob("*.py")) if p.resolve() != this and (u := _reserved_uses(p))}
    assert not uses, f"reserved sample data used (independent evaluation only): {uses}"
    probe = tmp_path / "probe.py"  # the check itself finds each way in
    probe.write_text("from skimage import data\nimport matplotlib.cbook as c\nclip = 'x/vtest.avi'\n")
    assert _reserved_uses(probe) == ["skimage", "matplotlib.cbook", "'vtest.avi'"]
