"""A session whose journal holds records of another shape (issue 43, the hunt): a file
made elsewhere, by hand or damaged, where a metadata update is a number, a line is a
JSON list, a trial's index is text, an event's kind a table, a count "x", the layout
a word. Each ended info, info --json, check and export in a traceback; now such a record
is left out when the file is read (as a line cut by a crash is), the rest is read, and
check names it. Real HDF5 files, the real commands."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np
import pytest

from tactile_studio.cli import main
from tactile_studio.errors import EXIT_CHECK_FAIL
from tactile_studio.sensor.layout import get_layout
from tactile_studio.storage.format.session_writer import SessionWriter

pytestmark = pytest.mark.damaged_files

RECORDS = {
    "update-a-number": ({"type": "metadata", "update": 5},
                        "line 4: a metadata update that is not a table"),
    "a-json-list": ([1, 2, 3], "line 4: [1, 2, 3] is not a record"),
    "a-json-string": ("x", "line 4: 'x' is not a record"),
    "layout-a-word": ({"type": "metadata", "update": {"layout": "x", "notes": "kept"}},
                      "line 4: metadata layout is 'x', not a table"),
    "gestures-a-number": ({"type": "metadata", "update": {"gestures": 5}},
                          "line 4: metadata gestures is 5, not a list"),
    "trial-index-text": ({"type": "trial", "index": "abc", "gesture": "x"},
                         "line 4: trial record whose index is 'abc', not a whole number"),
    "update-index-list": ({"type": "trial_update", "index": [1]},
                          "line 4: trial_update record whose index is [1]"),
    "event-kind-a-table": ({"type": "event", "kind": {"a": 1}, "frame": 3, "time": 1.0},
                           "line 4: event record whose kind is {'a': 1}, not text"),
    "lost-as-text": ({"type": "event", "kind": "overrun", "frame": 3, "time": 1.0,
                      "lost": "x"}, "line 4: event record whose lost is 'x'"),
    "counts-as-text": ({"type": "counters", "gaps": "x", "malformed_by_kind": {}},
                       "line 4: counters record whose gaps is 'x'"),
    "truncate-without-rows": ({"type": "truncate"}, "line 4: truncate record without rows"),
}


def _session_with(path: Path, record: object) -> Path:
    layout = get_layout("shearsense-6x6")
    n = 40
    with SessionWriter(path, layout, {"plugin": "simulated", "layout": layout.name,
                                      "nominal_rate_hz": 43.0}, {"source": "collect"}) as w:
        w.append_frames(np.full((n, layout.n_channels), 1000, np.uint16), np.arange(n) / 43,
                        1e9 + np.arange(n) / 43)
        w.add_trial({"index": 0, "gesture": "Poke", "key": "p", "start_sample": 2,
                     "end_sample": 10, "start_time": 0.0, "end_time": 0.2})
    with h5py.File(path, "r+") as f:  # the record, after the writer's own three lines
        lines = bytes(f["journal"][:]).split(b"\n")
        lines.insert(3, json.dumps(record).encode())
        del f["journal"]
        f.create_dataset("journal", data=np.frombuffer(b"\n".join(lines), np.uint8),
                         maxshape=(None,), chunks=True)
    return path


@pytest.mark.parametrize("case", RECORDS, ids=RECORDS)
def test_a_record_of_another_shape_is_left_out_and_named(tmp_path: Path, capsys,
                                                          case: str) -> None:
    record, named = RECORDS[case]
    path = _session_with(tmp_path / "s.h5", record)
    out = tmp_path / "out"
    out.mkdir()
    for argv in (["info", str(path)], ["info", "--json", str(path)],
                 ["export", str(path), "--format", "npz", "--out", str(out)],
                 ["export", str(path), "--format", "xdf", "--out", str(out)]):
        assert main(argv) == 0, argv  # a traceback escapes main and fails here
    summary = json.loads(_json_of(path, capsys))
    assert summary["frames"] == 40 and len(summary["trials"]) == 1  # the rest is read
    assert main(["check", str(path)]) == EXIT_CHECK_FAIL
    err = capsys.readouterr().err
    assert f"journal {named}" in err and "(left out when read)" in err, err


def _json_of(path: Path, capsys) -> str:
    capsys.readouterr()
    assert main(["info", "--json", str(path)]) == 0
    return capsys.readouterr().out
