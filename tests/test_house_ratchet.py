"""The house's ratchet (tools/house_ratchet.py) sees a figure rise and the seams stay strict."""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tools"))

import house_ratchet  # noqa: E402


def _house(tmp_path: Path, body: str) -> Path:
    for package in house_ratchet.PACKAGES:
        (tmp_path / package).mkdir()
    (tmp_path / "tactile_studio" / "m.py").write_text(body)
    return tmp_path


def test_an_any_a_wide_and_a_long_function_are_counted_and_a_rise_is_named(tmp_path):
    params = ", ".join(f"p{i}: int" for i in range(10))
    lines = "\n".join(f"    x{i} = {i}" for i in range(81))
    body = ("from typing import Any\n\n"
            "def f(a: Any, b: dict[str, Any]) -> Any: ...\n\n"
            f"def wide(self, {params}) -> None: ...\n\n"
            f"def narrow(self, {', '.join(f'p{i}: int' for i in range(9))}) -> None: ...\n\n"
            f"def long() -> None:\n{lines}\n")
    figures = house_ratchet.source_figures(_house(tmp_path, body))
    assert figures == {"any_bare": 2, "any_in_signatures": 3,
                       "functions_10_or_more_parameters": 1, "functions_over_80_lines": 1}
    recorded = {**figures, "any_bare": 1}
    (rise,) = house_ratchet.compare(figures, recorded)
    assert rise.startswith("any_bare: 2 (recorded 1)")
    assert house_ratchet.compare(figures, {**figures, "any_in_signatures": 9}) == []


def test_the_recorded_figures_hold_for_the_source():
    """The same check `make lint` makes, without mypy (slow): no source figure rose."""
    import json

    recorded = json.loads(house_ratchet.RECORD.read_text())
    assert house_ratchet.compare(house_ratchet.source_figures(), recorded) == []
