"""Every relative link in README.md and docs/ points at a file that exists, and a link to
a section (``page.md#anchor``) at a heading that page has: when docs/learning.md was split
into docs/learning/, links into its moved sections would otherwise have gone on pointing
at the top of the index."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")
ANCHORED = re.compile(r"\]\(([^)#\s]*)#([^)\s]+)\)")
FENCE = re.compile(r"```.*?```", re.S)
HEADING = re.compile(r"^#{1,6} (.+)$", re.M)


def _docs() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def anchors(page: Path) -> set[str]:
    """The anchors GitHub gives a page's headings: lower case, punctuation dropped, spaces
    to hyphens, a repeated heading numbered (-1, -2...)."""
    counts: dict[str, int] = {}
    found = set()
    for heading in HEADING.findall(FENCE.sub("", page.read_text(encoding="utf-8"))):
        slug = re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")
        n = counts.get(slug, 0)
        counts[slug] = n + 1
        found.add(slug if n == 0 else f"{slug}-{n}")
    return found


def broken_anchors(docs: list[Path], root: Path = ROOT) -> list[str]:
    broken = []
    for doc in docs:
        for target, anchor in ANCHORED.findall(FENCE.sub("", doc.read_text(encoding="utf-8"))):
            page = doc.parent / target if target else doc
            if re.match(r"^[a-z]+:", target) or page.suffix != ".md" or not page.exists():
                continue  # a web link, or a missing file (test_relative_links_resolve says so)
            if anchor not in anchors(page):
                broken.append(f"{doc.relative_to(root)}: {target}#{anchor}")
    return broken


def test_relative_links_resolve():
    broken = []
    for doc in _docs():
        for target in LINK.findall(doc.read_text(encoding="utf-8")):
            if re.match(r"^[a-z]+:", target):  # http:, mailto: ...
                continue
            if not (doc.parent / target).exists():
                broken.append(f"{doc.relative_to(ROOT)}: {target}")
    assert not broken, "broken links:\n" + "\n".join(broken)


def test_links_to_a_section_name_a_heading_of_that_page():
    broken = broken_anchors(_docs())
    assert not broken, "links to sections that do not exist:\n" + "\n".join(broken)


def test_the_anchor_checker_sees_a_moved_section(tmp_path):
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "learning.md").write_text("# Index\n\n## In short: which model\n")
    (tmp_path / "docs" / "models.md").write_text(
        "[ok](learning.md#in-short-which-model) [moved](learning.md#the-full-presets)\n")
    assert broken_anchors([tmp_path / "docs" / "models.md"], tmp_path) == [
        "docs/models.md: learning.md#the-full-presets"]


def test_the_checker_sees_links():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(LINK.findall(readme)) >= 3  # the screenshots at least
