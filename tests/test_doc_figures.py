"""Every figure the README and the docs quote comes from a benchmark that prints it, with
the date it was measured beside it (issue 47: "about 12x smaller than CSV" measured 6.7x,
"147k frames" for a full shear9 run was 81,776, and a sweep timing no benchmark printed).

Checked here: each row of the README's performance table names an existing
``benchmarks/bench_*.py`` and a date; every paragraph of README.md and docs/*.md (not
docs/learning/, which the learning work keeps) that quotes a measured figure beside a
benchmark dates it, and every benchmark a doc names exists.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DATE = re.compile(r"20\d\d-\d\d-\d\d")
BENCH = re.compile(r"bench_(\w+?)(?:\.py)?\b")
FIGURE = re.compile(r"\d[\d,.]*\s?(?:ms|µs|s|MB|KB/s|GB|%|x|fps|frames/s|rows/s|lines/s|"
                    r"min)\b")


def docs() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def paragraphs(text: str) -> list[str]:
    """Blank-line separated blocks; a table's rows one by one."""
    out = []
    for block in re.split(r"\n\s*\n", text):
        rows = [ln for ln in block.splitlines() if ln.startswith("|")]
        out.extend(rows if rows and len(rows) == len(block.splitlines()) else [block])
    return out


def performance_rows() -> list[str]:
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    start = lines.index("| what | figure | benchmark, measured |")
    rows = []
    for line in lines[start + 2:]:
        if not line.startswith("|"):
            break
        rows.append(line)
    return rows


def test_every_performance_row_names_its_benchmark_and_date():
    rows = performance_rows()
    assert len(rows) > 20
    for row in rows:
        cells = [c.strip() for c in row.strip().strip("|").split(" | ")]
        assert len(cells) == 3, row[:80]
        names = BENCH.findall(cells[2])
        assert names and DATE.search(cells[2]), row[:80]
        for name in names:
            assert (ROOT / "benchmarks" / f"bench_{name}.py").is_file(), (name, row[:80])


def test_every_benchmarked_figure_in_the_docs_is_dated():
    undated, missing = [], []
    for doc in docs():
        for par in paragraphs(doc.read_text(encoding="utf-8")):
            names = BENCH.findall(par)
            for name in names:
                if not (ROOT / "benchmarks" / f"bench_{name}.py").is_file():
                    missing.append(f"{doc.name}: bench_{name}")
            if (names or "python -m benchmarks" in par) and FIGURE.search(par) \
                    and not DATE.search(par):
                undated.append(f"{doc.name}: {par.strip()[:90]}")
    assert not missing, missing
    assert not undated, "figures without the date they were measured:\n" + "\n".join(undated)


def test_every_measured_section_is_dated():
    """A section whose heading says it is measured (or names its benchmark) dates its
    figures: "## Measured (benchmarks/bench_health.py ...)" with bullets of numbers."""
    undated = []
    for doc in docs():
        for section in re.split(r"\n(?=#+ )", doc.read_text(encoding="utf-8")):
            heading = section.splitlines()[0] if section.strip() else ""
            if heading.startswith("#") and re.search(r"measured|performance|bench_",
                                                     heading, re.IGNORECASE) \
                    and FIGURE.search(section) and not DATE.search(section):
                undated.append(f"{doc.name}: {heading}")
    assert not undated, undated
