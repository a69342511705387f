"""The layer contracts in ``pyproject.toml`` ([tool.importlinter]) hold: imports point down
(cli > gui > ops, sim > io > model > core), Qt only under gui/, rasterio and pyproj only in io/
(and the simulator); the import graph of the package has no circle, and an import inside a
function is there only to keep start-up short, and says so."""
import ast
import shutil
import subprocess
import sys
from pathlib import Path

import grimp

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "prismstation"


def test_import_contracts_are_kept():
    exe = Path(sys.executable).with_name("lint-imports")
    cmd = [str(exe)] if exe.exists() else [shutil.which("lint-imports") or "lint-imports"]
    run = subprocess.run(cmd + ["--no-cache"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout[-4000:] + run.stderr[-2000:]
    assert "BROKEN" not in run.stdout


def circles(edges: dict) -> list[set]:
    """The strongly connected components of more than one module of the graph ``edges``
    (module → the modules it imports): every import circle (Tarjan's algorithm)."""
    index, low, on, stack, out = {}, {}, set(), [], []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in edges.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = set()
            while True:
                w = stack.pop()
                on.discard(w)
                comp.add(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(comp)

    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10000))
    for v in list(edges):
        if v not in index:
            visit(v)
    return out


def test_circles_are_found():
    assert circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [{"a", "b", "c"}]
    assert circles({"a": {"b"}, "b": set()}) == []


def test_the_import_graph_has_no_circle():
    """grimp reads every import statement, those inside functions too: an import moved into a
    function does not hide a circle from this test."""
    graph = grimp.build_graph("prismstation")
    edges = {m: graph.find_modules_directly_imported_by(m) for m in graph.modules}
    found = circles(edges)
    assert not found, "import circles: " + "; ".join(" ↔ ".join(sorted(c)) for c in found)


def function_imports(path: Path) -> list[tuple[int, str]]:
    """``(line, module)`` of every import of a ``prismstation`` module inside a function of
    the file ``path`` whose line, or the comment right above its block of imports, does not
    say ``start-up``."""
    text = path.read_text(encoding="utf-8")
    lines = text.splitlines()
    bad = []
    for fn in ast.walk(ast.parse(text)):
        if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        for node in ast.walk(fn):
            if isinstance(node, ast.ImportFrom) and node.level == 0:
                names = [node.module or ""]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            else:
                continue
            if not any(n == "prismstation" or n.startswith("prismstation.") for n in names):
                continue
            k = node.lineno - 1
            said = lines[k]
            while k > 0 and lines[k - 1].strip().startswith(("from ", "import ", "#")):
                k -= 1
                said += lines[k]
            if "start-up" not in said:
                bad.append((node.lineno, names[0]))
    return bad


def test_imports_inside_functions_only_keep_start_up_short():
    """A module of the package imported inside a function, not at the top, only where that
    keeps start-up short (the simulator, Qt, a reader a command may not need), with a comment
    that says so (``# start-up: …``)."""
    bad = [f"{p.relative_to(SRC)}:{line}: {mod}" for p in sorted(SRC.rglob("*.py"))
           for line, mod in function_imports(p)]
    assert not bad, "imports inside functions without a start-up reason:\n" + "\n".join(bad)


def test_benchmarks_use_the_package_not_the_tests():
    """A benchmark measures what the package does with what the package offers: it never
    imports from ``tests/`` (its simulated projects are :mod:`prismstation.sim`'s)."""
    bad = []
    for p in sorted((ROOT / "benchmarks").glob("*.py")):
        for node in ast.walk(ast.parse(p.read_text(encoding="utf-8"))):
            names = ([node.module or ""] if isinstance(node, ast.ImportFrom) and node.level == 0
                     else [a.name for a in node.names] if isinstance(node, ast.Import) else [])
            bad += [f"{p.name}:{node.lineno}: {n}" for n in names if n == "tests" or n.startswith("tests.")]
    assert not bad, "benchmarks importing from tests/:\n" + "\n".join(bad)
