"""docs/architecture.md's map of the package is true: every module of ``src/prismstation`` is
on it, under its own package's heading, and every module it names exists there."""
from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "prismstation"
DOC = ROOT / "docs" / "architecture.md"


def map_sections(text: str) -> dict[str, set[str]]:
    """Package (``"core/"``, ``"gui/tools/"``) → the module file names (``"scene.py"``) its part
    of the section "A map of the package" names: the part runs from the package's bold heading
    (**`core/`**) to the next one."""
    start = text.index("## A map of the package")
    end = text.index("\n## ", start + 1)
    parts = re.split(r"\*\*`([a-z_/]+/)`\*\*", text[start:end])
    return {parts[i]: set(re.findall(r"(?<![\w/])(\w+\.py)\b", parts[i + 1])) for i in range(1, len(parts), 2)}


def holds_nothing(path: Path) -> bool:
    """An ``__init__.py`` with no statement beyond its docstring (a package marker)."""
    body = ast.parse(path.read_text(encoding="utf-8")).body
    return path.name == "__init__.py" and all(
        isinstance(n, ast.Expr) and isinstance(n.value, ast.Constant) or isinstance(n, ast.ImportFrom)
        and n.module == "__future__" for n in body)


def modules() -> dict[str, set[str]]:
    """Package → the modules in it that the map must name (top-level modules aside: the
    section "Layers" names them)."""
    out: dict[str, set[str]] = {}
    for p in sorted(SRC.rglob("*.py")):
        if p.parent != SRC and not holds_nothing(p):
            out.setdefault(f"{p.parent.relative_to(SRC).as_posix()}/", set()).add(p.name)
    return out


def test_the_map_is_read():
    sections = map_sections(DOC.read_text(encoding="utf-8"))
    assert {"core/", "io/", "ops/", "gui/", "cli/"} <= set(sections)
    assert "solution.py" in sections["core/"] or any("solution.py" in s for s in sections.values())


def test_every_module_is_on_the_map():
    sections = map_sections(DOC.read_text(encoding="utf-8"))
    missing = [f"{pkg}{m}" for pkg, names in modules().items() for m in sorted(names - sections.get(pkg, set()))]
    assert not missing, "modules not on docs/architecture.md's map (§A map of the package):\n" + "\n".join(missing)


def test_every_module_on_the_map_exists():
    sections = map_sections(DOC.read_text(encoding="utf-8"))
    stale = [f"{pkg}{m}" for pkg, names in sections.items() for m in sorted(names)
             if not (SRC / pkg / m).is_file()]
    assert not stale, "docs/architecture.md's map names modules that are not there:\n" + "\n".join(stale)
