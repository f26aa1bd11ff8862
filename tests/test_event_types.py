"""Events are declared once as types (issue 44): the collection runner, driven on a real
stream into a real session file, sends only protocol/runner_events.py's types, their plain
form is what the marker stream always carried (the session file it wrote passes `check`:
conftest checks every file a test writes), and no ui module compares an event's kind
to a string (it switches on the type)."""

from __future__ import annotations

import ast
from pathlib import Path

from collect_fixtures import do_trial, make_rig, mini_protocol, start

from tactile_studio.protocol.runner_events import (
    KINDS,
    BlockStarted,
    NoteAdded,
    Refused,
    StateChanged,
    TrialEnded,
    TrialStarted,
    TrialUpdated,
)
from tactile_studio.storage.format.trials import TrialRecord
from tactile_studio.streams.markers import runner_marker

UI = Path(__file__).resolve().parents[1] / "ui"
EVENT_NAMES = ("e", "ev", "event")


def test_every_event_a_runner_sends_is_a_declared_type(tmp_path: Path) -> None:
    rig = make_rig(tmp_path, mini_protocol(2), "P03", speed=60.0)
    r = rig.runner
    seen: list[object] = []
    r.add_listener(seen.append)
    try:
        assert not r.key("?")  # before the start: refused, with a hint
        start(rig)
        assert r.add_note("the participant is settled")
        t0 = do_trial(rig, r.snapshot().remaining[0])
        assert r.discard(t0["index"], "sneezed")
    finally:
        rig.close()
    assert seen and all(isinstance(e, KINDS) for e in seen), \
        [e for e in seen if not isinstance(e, KINDS)]
    kinds = {type(e) for e in seen}
    assert {Refused, StateChanged, BlockStarted, NoteAdded, TrialStarted, TrialEnded,
            TrialUpdated} <= kinds
    ended = next(e for e in seen if isinstance(e, TrialEnded))
    record = ended.to_record()
    assert list(record) == ["kind", "trial", "flags", "reason"]
    assert record["kind"] == "trial_ended" and record["flags"] == t0["flags"]
    # the event carries the typed record; its plain form is the file's trial
    assert isinstance(ended.trial, TrialRecord) and record["trial"] == ended.trial.to_dict()
    updated = next(e for e in seen if isinstance(e, TrialUpdated))
    assert runner_marker(updated)["kind"] == "discard"
    assert runner_marker(ended)["kind"] == "trial_end"


def _kind_of_event(node: ast.expr, aliases: frozenset[str] = frozenset()) -> bool:
    """``event["kind"]``, ``event.get("kind")``, ``ev.kind``, or a name one of them was
    given to (``kind = event["kind"]``)."""
    if isinstance(node, ast.Subscript):
        return isinstance(node.slice, ast.Constant) and node.slice.value == "kind"
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
        return node.func.attr == "get" and bool(node.args) and \
            isinstance(node.args[0], ast.Constant) and node.args[0].value == "kind"
    if isinstance(node, ast.Attribute) and node.attr == "kind":
        base = node.value
        return isinstance(base, ast.Name) and (base.id in EVENT_NAMES
                                                or base.id.endswith("event"))
    return isinstance(node, ast.Name) and node.id in aliases


def _is_text(node: ast.expr) -> bool:
    if isinstance(node, (ast.Tuple, ast.List, ast.Set)):
        return any(_is_text(x) for x in node.elts)
    return isinstance(node, ast.Constant) and isinstance(node.value, str)


def string_kind_comparisons(root: Path) -> list[str]:
    """Every comparison of an event's kind with a string under ``root``, as path:line."""
    found = []
    for path in sorted(root.rglob("*.py")):
        tree = ast.parse(path.read_text(), str(path))
        aliases = frozenset(t.id for node in ast.walk(tree) if isinstance(node, ast.Assign)
                            and _kind_of_event(node.value)
                            for t in node.targets if isinstance(t, ast.Name))
        for node in ast.walk(tree):
            if not isinstance(node, ast.Compare):
                continue
            sides = [node.left, *node.comparators]
            if any(_kind_of_event(s, aliases) for s in sides) and any(map(_is_text, sides)):
                found.append(f"{path.relative_to(root.parent)}:{node.lineno}")
    return found


def test_the_ui_switches_on_event_types_never_on_kind_strings() -> None:
    assert string_kind_comparisons(UI) == []


def test_the_scan_sees_a_kind_compared_to_a_string(tmp_path: Path) -> None:
    (tmp_path / "ui").mkdir()
    (tmp_path / "ui" / "w.py").write_text(
        "def on(event, ev):\n"
        "    if event['kind'] == 'health':\n        pass\n"
        "    if ev.kind in ('phase', 'spot'):\n        pass\n"
        "    kind = event.get('kind')\n    if kind == 'x':\n        pass\n")
    assert string_kind_comparisons(tmp_path / "ui") == ["ui/w.py:2", "ui/w.py:4", "ui/w.py:7"]
