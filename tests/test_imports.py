"""The package's layers import one way: no module imports one that imports it back (directly or through others)."""

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "hvs_sim"


def _module_name(path: Path) -> str:
    rel = path.relative_to(PACKAGE.parent).with_suffix("")
    parts = rel.parts[:-1] if rel.name == "__init__" else rel.parts
    return ".".join(parts)


def _imports(path: Path, modules: set[str]) -> set[str]:
    """hvs_sim modules a module imports, anywhere in it (function-level and TYPE_CHECKING imports included)."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        names = []
        if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("hvs_sim"):
            names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
        elif isinstance(node, ast.Import):
            names = [a.name for a in node.names if a.name.startswith("hvs_sim")]
        out |= {n for n in names if n in modules}
    return out


def test_no_import_cycles():
    paths = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    graph = {m: _imports(p, set(paths)) - {m} for m, p in paths.items()}
    packages = {m for m, p in paths.items() if p.name == "__init__.py"}

    def reach(start):
        seen, todo = set(), [start]
        while todo:
            for n in graph[todo.pop()]:
                if n not in seen:
                    seen.add(n)
                    todo.append(n)
        return seen

    # a package's __init__ re-exporting its own modules is not a cycle between layers
    cycles = sorted((a, b) for a in graph for b in graph[a]
                    if a in reach(b) and not (a in packages and b.startswith(a + ".")) and
                    not (b in packages and a.startswith(b + ".")))
    assert not cycles, cycles
