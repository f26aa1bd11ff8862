"""Taxel names, the one parser: every place that asks for a taxel accepts its name or index.

Screens, reports and the heatmap name taxels by row letter and 1-based column (A1 at the
top left, F6 at the bottom right of the 6x6 array); older options and files use indices
(0..35, as the layout orders them). ``parse_taxel`` takes either ("C3", "c3", "14"),
``parse_taxels`` a comma list or "all", and ``taxel_label`` gives the name back. Plugin
settings of kind ``taxel`` keep the text checked by :func:`taxel_token` (no layout known
yet) and the device resolves it against its own layout.
"""

from __future__ import annotations

import re

from tactile_studio.errors import UserError
from tactile_studio.sensor.layout import Layout

_NAME = re.compile(r"\s*([A-Za-z]{1,2})(\d+)\s*")
_INDEX = re.compile(r"\s*(\d+)\s*")


def taxel_label(layout: Layout, taxel: int) -> str:
    """The taxel's name on ``layout`` ("C3")."""
    return layout.taxel_name(*layout.taxel_rc(taxel))


def _row(letters: str) -> int:
    letters = letters.upper()
    if len(letters) == 1:
        return ord(letters) - ord("A")
    return (ord(letters[0]) - ord("A") + 1) * 26 + ord(letters[1]) - ord("A")


def _range(layout: Layout) -> str:
    last = layout.taxel_name(layout.rows - 1, layout.cols - 1)
    return f"A1..{last}) or an index (0..{layout.n_taxels - 1}"


def parse_taxel(layout: Layout, spec: str | int) -> int:
    """Taxel index from a name ("B2": row B, column 2) or an index ("7"); UserError
    naming the valid range if it is not on the array."""
    if isinstance(spec, int) and not isinstance(spec, bool):
        if 0 <= spec < layout.n_taxels:
            return spec
    else:
        text = str(spec)
        m = _NAME.fullmatch(text)
        if m:
            row, col = _row(m.group(1)), int(m.group(2)) - 1
            if 0 <= row < layout.rows and 0 <= col < layout.cols:
                return layout.taxel_at(row, col)
        m = _INDEX.fullmatch(text)
        if m and int(m.group(1)) < layout.n_taxels:
            return int(m.group(1))
    raise UserError(f"{str(spec).strip()!r} is not a taxel of {layout.name} ({_range(layout)})")


def parse_taxels(layout: Layout, spec: str) -> list[int]:
    """``"B2,B5"``, ``"7,10"`` or ``"all"`` -> taxel indices (all: row by row)."""
    if spec.strip().lower() == "all":
        return sorted(range(layout.n_taxels), key=lambda t: layout.taxel_rc(t))
    out = [parse_taxel(layout, part) for part in spec.split(",") if part.strip()]
    if not out:
        raise UserError("no taxels given")
    return out


def distinct_taxels(layout: Layout, taxels: list[int]) -> list[int]:
    """``taxels`` when none is named twice ("B2,b2", "B2,7"), else a UserError naming it:
    a calibration then held two curves for one taxel, a characterisation measured it
    twice and kept the second."""
    seen: set[int] = set()
    twice = [t for t in taxels if t in seen or seen.add(t)]
    if twice:
        names = ", ".join(dict.fromkeys(layout.taxel_name(*layout.taxel_rc(t)) for t in twice))
        raise UserError(f"taxels named more than once: {names}")
    return taxels


def taxel_token(value: str | int) -> str | int:
    """A taxel setting checked without a layout: an index stays an int, a name is kept
    upper-case ("c3" -> "C3"); ValueError if it is neither."""
    if isinstance(value, int) and not isinstance(value, bool):
        return value
    text = str(value).strip()
    if _INDEX.fullmatch(text):
        return int(text)
    if _NAME.fullmatch(text):
        return text.upper()
    raise ValueError(text)
