"""learn/ stays in rooms: a researcher finds "where is export" by the room's name, so the
package holds rooms only (no loose modules) and each room stays a handful of modules,
each room saying in its docstring what it holds."""

from __future__ import annotations

import ast
from pathlib import Path

import tactile_studio.learn as learn

ROOMS = {"data", "models", "learners", "experiments", "evaluation", "results", "deploy"}
LEARN = Path(learn.__file__).parent


def test_learn_holds_rooms_only() -> None:
    # below every room: the declarations all of them read (lists of choices, presets)
    shared = {"__init__.py", "choices.py", "presets.py"}
    loose = sorted(p.name for p in LEARN.glob("*.py") if p.name not in shared)
    assert loose == [], f"modules outside a room in learn/: {loose}"
    rooms = {p.name for p in LEARN.iterdir() if (p / "__init__.py").is_file()}
    assert rooms == ROOMS


def test_each_room_is_a_handful_of_modules_and_says_what_it_holds() -> None:
    for room in sorted(ROOMS):
        modules = [p for p in (LEARN / room).glob("*.py") if p.name != "__init__.py"]
        assert 3 <= len(modules) <= 12, f"learn/{room} has {len(modules)} modules"
        doc = ast.get_docstring(ast.parse((LEARN / room / "__init__.py").read_text()))
        assert doc and len(doc.split()) >= 10, f"learn/{room}/__init__.py says nothing"



def test_the_docs_have_a_page_per_room() -> None:
    docs = Path(__file__).resolve().parents[1] / "docs" / "learning"
    missing = sorted(r for r in ROOMS - {"models"} if not (docs / f"{r}.md").is_file())
    assert missing == [], f"docs/learning/ lacks a page for {missing}"
