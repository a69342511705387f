"""The README and docs/ are self-contained: every link resolves to a file (and heading) inside
the repository, and the README's set-up and test commands are what CI runs."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
REF = re.compile(r"^\s*\[[^\]]+\]:\s*(\S+)", re.MULTILINE)
BARE = re.compile(r"<((?:https?|ftp|file)://[^>]+)>|(?<![(\w])((?:https?|ftp|file)://\S+)")


def _prose(text: str) -> str:
    """``text`` without fenced code blocks and inline code (their brackets are not links)."""
    text = re.sub(r"^```.*?^```", "", text, flags=re.MULTILINE | re.DOTALL)
    return re.sub(r"`[^`\n]*`", "", text)


def _slug(heading: str) -> str:
    """The anchor a Markdown renderer gives a heading (GitHub's rule)."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def _anchors(md: Path) -> set:
    text = re.sub(r"^```.*?^```", "", md.read_text(encoding="utf-8"), flags=re.MULTILINE | re.DOTALL)
    return {_slug(m.group(1).replace("`", "")) for m in re.finditer(r"^#+\s+(.+?)\s*#*$", text, re.MULTILINE)}


def links(md: Path) -> list[str]:
    text = _prose(md.read_text(encoding="utf-8"))
    found = [m.group(1) for m in LINK.finditer(text)] + REF.findall(text) + \
        [a or b for a, b in BARE.findall(text)]
    return list(dict.fromkeys(found))


def problems(md: Path) -> list[str]:
    """Every link of ``md`` that leaves the repository or points at nothing."""
    out = []
    for target in links(md):
        if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.IGNORECASE):
            out.append(f"{target}: leaves the repository")
            continue
        path, _, anchor = target.partition("#")
        dest = (md.parent / path).resolve() if path else md.resolve()
        if path.startswith("/") or not dest.is_relative_to(ROOT):
            out.append(f"{target}: leaves the repository")
        elif not dest.exists():
            out.append(f"{target}: no such file")
        elif anchor and dest.suffix == ".md" and anchor not in _anchors(dest):
            out.append(f"{target}: no heading #{anchor} in {dest.name}")
    return [f"{md.relative_to(ROOT)}: {p}" for p in out]


@pytest.mark.parametrize("md", DOCS, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_link_stays_inside_the_repository(md):
    assert links(md) or md.name != "README.md"  # the README does link its docs
    assert problems(md) == []


def test_the_checker_catches_what_it_must(tmp_path, monkeypatch):
    monkeypatch.setattr(f"{__name__}.ROOT", tmp_path)
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "b.md").write_text("# Two words: here\n")
    md = tmp_path / "docs" / "a.md"
    md.write_text("[ok](b.md#two-words-here) ![pic](b.md) `[code](../x.md)`\n"
                  "[up](../../shared/design/FORMATS.md) [web](https://example.org/x) "
                  "see <https://example.org> [gone](c.md) [bad](b.md#nope) [abs](/etc/passwd)\n"
                  "[r]: http://example.com\n```\n[fenced](../x.md)\n```\n")
    got = problems(md)
    assert [p.split(": ", 1)[1] for p in got] == [
        "../../shared/design/FORMATS.md: leaves the repository",
        "https://example.org/x: leaves the repository",
        "c.md: no such file", "b.md#nope: no heading #nope in b.md",
        "/etc/passwd: leaves the repository", "http://example.com: leaves the repository",
        "https://example.org: leaves the repository"]


def test_readme_commands_are_what_ci_runs():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    blocks = re.findall(r"^```sh\n(.*?)^```", readme, re.MULTILINE | re.DOTALL)
    ci = [ln for ln in (ROOT / ".ci" / "run").read_text().splitlines()
          if ln.strip() and not ln.startswith(("#", "set ", "cd "))]
    assert ci == ["bash packaging/setup.sh --test && .venv/bin/python -m pytest -n 2"]
    assert ci[0] in [b.strip() for b in blocks]
    assert "bash packaging/setup.sh && .venv/bin/prismstation demo" in [b.strip() for b in blocks]
    setup = (ROOT / "packaging" / "setup.sh").read_text()
    assert "poppler-utils" in setup  # the PDF report test reads its output with poppler's tools


def test_nothing_names_a_tracker_issue():
    """Code, tests, benchmarks and docs say what a thing does, not which ticket asked for it:
    no "Issue N" (a number that means nothing inside the repository)."""
    pattern = re.compile(r"\bissues?\s*#?\s*\d+", re.IGNORECASE)
    files = [ROOT / "README.md", ROOT / "pyproject.toml", *DOCS] + [
        p for d in ("src", "tests", "benchmarks", "packaging", ".ci") for p in (ROOT / d).rglob("*")
        if (p.suffix in (".py", ".md", ".toml", ".cfg", ".sh", ".txt") or p.parent.name == ".ci") and p.is_file()]
    found = [f"{p.relative_to(ROOT)}:{text.count(chr(10), 0, m.start()) + 1}: {m.group(0)}"
             for p in dict.fromkeys(files) for text in [p.read_text(encoding="utf-8", errors="replace")]
             for m in pattern.finditer(text)]
    assert not found, "\n".join(found)
