"""The Sensors window does not draw a calibration as drift (issue 47, item 22): ratios
against the nominal curve (1.29) and against a calibration (~1.0) were one line on one
axis, and three checks made at the same hours showed as two squares."""

from __future__ import annotations

import pytest
from PySide6.QtCore import Qt

from tactile_studio.storage.books.logbook import Logbook


@pytest.fixture(autouse=True)
def data_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("TACTILE_STUDIO_DATA_DIR", str(tmp_path / "data"))


KPA = {"normal_kpa": 10.0, "shear_kpa": 0.0}


def check(book: Logbook, ratio: float, reference: str, **result) -> int:
    spot = {"taxel": "E5", "normal_kpa": 10 * ratio, "shear_kpa": 0.0, "ratio": ratio,
            "verdict": "pass" if ratio < 1.25 else "warn", "reference": reference}
    return book.add_check("S9", {"verdict": spot["verdict"], "weight_g": 200,
                                 "reasons": [], "spots": [spot], **result})


def test_a_calibration_starts_a_new_line_and_every_check_is_seen(qtbot):
    from tactile_studio.ui.sensors_window import SensorsWindow
    with Logbook() as book:
        book.ensure_sensor("S9")
        check(book, 1.29, "nominal")          # a new sensor, against the nominal curve
        check(book, 1.28, "nominal")          # again, same hours (nothing recorded)
        cal = book.add_calibration("S9", "plate", 0.1, {"fits": []})
        check(book, 1.01, f"calibration #{cal}", reference_calibration=cal)
        book.add_usage("S9", 3600.0 * 5)
        check(book, 0.97, f"calibration #{cal}", reference_calibration=cal)
    w = SensorsWindow()
    qtbot.addWidget(w)
    w.show()
    assert w.sensors.currentItem().text() == "S9"
    # two lines for E5: against the nominal curve (dashed, hollow), then the calibration
    runs = [(spot, ref, list(item.getData()[1])) for spot, ref, item in w.segments]
    assert runs == [("E5", "nominal", [1.29, 1.28]), ("E5", "calibration #1", [1.01, 0.97])]
    nominal_item = w.segments[0][2]
    assert nominal_item.opts["pen"].style() == Qt.PenStyle.DashLine
    assert nominal_item.opts["symbolBrush"] is None
    # the change of reference is marked where it happened, and said in words
    assert w.reference_marks == [(0.0, "nominal curve → calibration #1")]
    assert "a new reference starts a new line" in w.reference_note.text()
    assert "check #3 at 0 h: nominal curve → calibration #1" in w.reference_note.text()
    # four checks, four squares: the three at 0 h side by side, not on top of each other
    xs = [(x, y) for x, y, _ in w.verdict_points]
    assert len(set(xs)) == 4 and [i for *_, i in w.verdict_points] == [1, 2, 3, 4]


def test_an_older_check_without_per_spot_references_is_still_placed(qtbot):
    """Checks stored before spots carried their reference: the check's own fields say it."""
    from tactile_studio.ui.sensors_window import SensorsWindow
    with Logbook() as book:
        book.ensure_sensor("S9")
        first = book.add_check("S9", {"verdict": "pass", "weight_g": 200, "reasons": [],
                                      "spots": [{"taxel": "B2", "ratio": 1.1, **KPA,
                                                 "verdict": "pass"}]})
        book.add_check("S9", {"verdict": "pass", "weight_g": 200, "reasons": [],
                              "reference_check": first,
                              "spots": [{"taxel": "B2", "ratio": 0.99, **KPA,
                                         "verdict": "pass"}]})
    w = SensorsWindow()
    qtbot.addWidget(w)
    assert [(s, r) for s, r, _ in w.segments] == [("B2", "nominal"), ("B2", "check #1")]
