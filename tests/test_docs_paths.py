"""The documentation's citations hold: every results folder, doc or asset that README.md or docs/*.md names exists,
and the README stays a front door (short, the set-up commands first).

A path is checked when it is cited in inline backticks (each whitespace-separated word of the span that starts with
one of CHECKED_PREFIXES, e.g. the `--out` of a command) or as a markdown link or image target. Backtick paths are
read from the repository root; link targets from the file that holds them (as GitHub resolves them), then checked
from the root. Fenced code blocks are commands to type, not citations, and are not read; words with a `*`, `<` or
`{` are patterns or placeholders, and out/ is where runs write, so neither is checked.
"""

from __future__ import annotations

import re
from pathlib import Path, PurePosixPath

import pytest

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
DOC_FILES = [README, *sorted((ROOT / "docs").glob("*.md"))]
CHECKED_PREFIXES = ("experiments/results/", "docs/", "assets/")
MAX_README_LINES = 200

FENCE = re.compile(r"^[ \t]*(```|~~~).*?^[ \t]*\1[^\n]*$", re.DOTALL | re.MULTILINE)
INLINE = re.compile(r"(`+)(.+?)\1", re.DOTALL)
LINK = re.compile(r"!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
PLACEHOLDER = re.compile(r"[*<>{}]")
# words a citation may be wrapped in or followed by in prose
STRIP = "\"'`,;:.()[]→"
# what a document that may be read on its own must not lean on: the notebook's time-bound references
TIME_BOUND = re.compile(r"\bstop \d+\b|\bthis stop\b|\bthe stop before\b|\bstops? ago\b|\b(?:the|this) issue\b",
                        re.IGNORECASE)


def _without_fences(text: str) -> str:
    return FENCE.sub("", text)


def cited_paths(doc: Path, text: str | None = None) -> list[tuple[str, str]]:
    """(as written, repository-relative path) of every checked citation in `doc` (or in `text`, read as if it
    were the file `doc`)."""
    text = _without_fences(doc.read_text(encoding="utf-8") if text is None else text)
    found: list[tuple[str, str]] = []
    for _, span in INLINE.findall(text):
        for word in span.split():
            word = word.strip(STRIP)
            if "=" in word:  # --out=experiments/results/x
                word = word.split("=", 1)[1]
            if word.startswith(CHECKED_PREFIXES):
                found.append((word, word))
    for target in LINK.findall(INLINE.sub("", text)):
        if "://" in target or target.startswith(("#", "mailto:")):
            continue
        target = target.split("#", 1)[0]
        if not target:
            continue
        rel = PurePosixPath(doc.parent.relative_to(ROOT).as_posix()) / target
        parts: list[str] = []
        for part in rel.parts:
            if part == "..":
                if parts:
                    parts.pop()
            elif part != ".":
                parts.append(part)
        resolved = "/".join(parts)
        if resolved.startswith(CHECKED_PREFIXES) or (resolved + "/").startswith(CHECKED_PREFIXES):
            found.append((target, resolved))
    return [(w, p) for w, p in found if not PLACEHOLDER.search(p) and not p.startswith("out/")]


@pytest.mark.parametrize("doc", DOC_FILES, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_cited_paths_exist(doc):
    missing = sorted({f"{written} (→ {path})" for written, path in cited_paths(doc)
                      if not (ROOT / path.rstrip("/")).exists()})
    assert not missing, f"{doc.relative_to(ROOT)} cites paths that do not exist: {missing}"


@pytest.mark.parametrize("doc", DOC_FILES, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_no_time_bound_references(doc):
    hits = [f"line {i}: {m.group(0)!r}" for i, line in enumerate(doc.read_text(encoding="utf-8").splitlines(), 1)
            for m in TIME_BOUND.finditer(line)]
    assert not hits, f"{doc.relative_to(ROOT)} refers to a moment of its writing: {hits}"


def test_readme_is_a_front_door():
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= MAX_README_LINES, f"README.md has {len(lines)} lines (at most {MAX_README_LINES})"
    starts = [i for i, line in enumerate(lines) if line.lstrip().startswith("```")]
    assert len(starts) >= 2, "README.md has no fenced code block"
    first, end = starts[0], starts[1]
    assert not any(line.strip() for line in lines[1:first] if not line.startswith("#")), \
        "README.md must begin (after its title) with the set-up commands"
    block = "\n".join(lines[first + 1:end])
    assert "make demo" in block and "make test" in block, \
        "README.md's first code block must hold `make demo` and `make test`"


def test_the_checker_sees_citations():
    """The path finder itself: backticks, words inside a command, links relative to their file, placeholders, out/
    and fenced blocks left alone."""
    text = ("`experiments/results/track/` and `hvs-sim bench track --out experiments/results/nope`, "
            "[a](../assets/weights/gru.json) ![b](../experiments/results/{x}/y.png) `out/x` `docs/x*.md` "
            "[c](plugins.md#naming) [d](https://example.org/docs/x)\n"
            "```bash\nhvs-sim run --out experiments/results/in_a_fence\n```\n")
    found = {path for _, path in cited_paths(ROOT / "docs" / "probe.md", text)}
    assert found == {"experiments/results/track/", "experiments/results/nope", "assets/weights/gru.json",
                     "docs/plugins.md"}
