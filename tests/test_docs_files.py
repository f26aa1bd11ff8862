"""The documentation names files that exist, and `make screenshots` makes every picture
the docs show.

Docs and docstrings pointed at ``docs/screenshots/make_*.py`` long after the makers moved
to ``tools/screenshots/``; pictures went stale because nothing said which maker draws
them. Static checks, no window opened.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCS = sorted((ROOT / "docs").rglob("*.md")) + [ROOT / "README.md"]  # docs/learning/ too
TOOLS = sorted((ROOT / "tools").rglob("*.py"))
REPO_PATH = re.compile(r"^(?:\./)?(?:docs|tools|resources|tests|tactile_studio|ui|plugins|"
                       r"benchmarks)/[\w./&-]+\.(?:py|png|toml|md|csv|json|qss|svg)$")
IMAGE = re.compile(r"!\[[^\]]*\]\(([^)\s]+)\)")
FENCE = re.compile(r"```.*?```", re.S)
INLINE = re.compile(r"`([^`\n]+)`")
RUN = re.compile(r"python3?\s+(\S+\.py)")  # a script a command runs


def _tokens(span: str) -> list[str]:
    return [t.strip(".") for t in re.split(r"[\s()\[\],;:'\"]+", span)]


def named_files(path: Path) -> list[str]:
    """Repo files a doc names: inline code spans, images, scripts its commands run (an
    example tree or a '# file:' of a plugin author's own package is not the repo's)."""
    text = path.read_text(encoding="utf-8")
    if path.suffix == ".py":
        return RUN.findall(text)
    fenced = " ".join(FENCE.findall(text))
    prose = FENCE.sub(" ", text)
    names = [t for span in INLINE.findall(prose) for t in _tokens(span)]
    names += RUN.findall(fenced)
    return [n for n in names if REPO_PATH.match(n) and not re.search(r"[*<>{}]", n)]


def test_every_file_the_docs_name_exists():
    missing = []
    for doc in DOCS + TOOLS:
        for name in named_files(doc):
            if not (ROOT / name).exists() and not (doc.parent / name).exists():
                missing.append(f"{doc.relative_to(ROOT)}: {name}")
        if doc.suffix == ".md":
            for src in IMAGE.findall(doc.read_text(encoding="utf-8")):
                if not src.startswith("http") and not (doc.parent / src).exists():
                    missing.append(f"{doc.relative_to(ROOT)}: image {src}")
    assert not missing, "docs name files that do not exist:\n" + "\n".join(missing)


def screenshot_makers() -> dict[Path, str]:
    """What `make screenshots` runs: every tools/screenshots/make_*.py, the protocol
    pictograms, and the test files the Makefile runs with TACTILE_STUDIO_SCREENSHOTS."""
    make = (ROOT / "Makefile").read_text()
    target = make.split("\nscreenshots:", 1)[1].split("\n\n", 1)[0]
    files = [ROOT / f for f in re.findall(r"(tests/\S+\.py|tools/\S+\.py)", target)]
    if "tools/screenshots/make_*.py" in target:
        files += sorted((ROOT / "tools" / "screenshots").glob("make_*.py"))
    return {f: f.read_text(encoding="utf-8") for f in files if f.is_file()}


def test_make_screenshots_draws_every_picture_the_docs_show():
    makers = screenshot_makers()
    assert any(p.name == "make_screenshots.py" for p in makers)
    source = "\n".join(makers.values())
    orphans = []
    for doc in DOCS:
        for src in IMAGE.findall(doc.read_text(encoding="utf-8")):
            pic = (doc.parent / src).resolve()
            if pic.parent != (ROOT / "docs" / "screenshots").resolve():
                continue
            # its name, or its name less a maker's prefix ("characterise-", "research_"),
            # is written by a maker
            rest = re.split(r"[-_]", pic.stem, maxsplit=1)[-1]
            if not any(f'"{n}' in source or f"'{n}" in source
                       for n in (pic.name, pic.stem, f"{rest}.png", rest)):
                orphans.append(f"{doc.relative_to(ROOT)}: {src}")
    assert not orphans, "pictures no maker of `make screenshots` draws:\n" + "\n".join(orphans)
