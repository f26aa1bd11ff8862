"""Terminal output: rich progress and tables in a terminal, plain text when piped or
under CI (no escape codes, no carriage returns), ``--json`` untouched."""

from __future__ import annotations

import io
import json
import os
import subprocess
import sys

import numpy as np
import pytest
from learn_fixtures import make_dataset_folder
from plugin_fixtures import LAYOUT

from tactile_studio.cli import main, tables
from tactile_studio.jobs import TerminalProgress
from tactile_studio.storage import SessionWriter


class FakeTerminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def _run(progress: TerminalProgress, steps: int = 50) -> None:
    for i in range(steps + 1):
        progress(i / steps, f"step {i}")


def test_piped_progress_is_a_few_plain_lines(monkeypatch):
    monkeypatch.delenv("CI", raising=False)
    out = io.StringIO()
    _run(TerminalProgress("job", stream=out))
    text = out.getvalue()
    assert "\x1b" not in text and "\r" not in text
    lines = text.splitlines()
    assert len(lines) == 11 and lines[0] == "job [  0%] step 0"
    assert lines[-1].startswith("job [100%] step 50 (") and lines[-1].endswith(" s)")


def test_ci_gets_plain_lines_even_on_a_terminal(monkeypatch):
    monkeypatch.setenv("CI", "true")
    out = FakeTerminal()
    progress = TerminalProgress("job", stream=out)
    progress.subtask("fold", "fold 1/3", 2, None, "epoch 2")  # nested rows: terminal only
    _run(progress)
    assert "\x1b" not in out.getvalue() and "fold 1/3" not in out.getvalue()


def test_terminal_gets_rich_bar_with_eta_rate_and_nested_rows(monkeypatch):
    monkeypatch.delenv("CI", raising=False)
    monkeypatch.setenv("TERM", "xterm")
    out = FakeTerminal()
    progress = TerminalProgress("train", stream=out, total=10, unit="s")
    progress(0.3, "round 1")
    progress.subtask("round", "round 1", 1, 3, "fold P01 accuracy 0.900")
    progress.subtask("fold", "fold 2/3 P02", 4, None, "epoch 4")
    progress(0.6, "round 1 fold 2")
    progress.close()
    text = out.getvalue()
    assert "\x1b[" in text and "train" in text and "ETA" in text
    assert "round 1" in text and "fold 2/3 P02" in text and "epoch 4" in text
    assert "s/s" in text or "0:00:00" in text
    progress(0.9, "after close")  # a closed display stays closed
    assert out.getvalue() == text


def test_tables_plain_when_piped_rich_in_a_terminal(monkeypatch):
    monkeypatch.delenv("CI", raising=False)
    monkeypatch.setenv("TERM", "xterm")
    rows = [("P01", "0.900"), ("P02\x1b[31m", "1.000")]
    piped = io.StringIO()
    tables.table(("fold", "accuracy"), rows, stream=piped, right=("accuracy",))
    assert piped.getvalue().splitlines() == ["fold      accuracy", "P01" + " " * 10 + "0.900",
                                             "P02 [31m" + " " * 5 + "1.000"]
    term = FakeTerminal()
    tables.table(("fold", "accuracy"), rows, stream=term)
    assert "━" in term.getvalue() or "─" in term.getvalue()
    assert "[31m" in term.getvalue()  # shown as text, never interpreted as markup


def _session(path) -> None:
    w = SessionWriter(path, LAYOUT, {"plugin": "counting"}, {"participant": "P07"})
    t = np.arange(100) / 100.0
    w.append_frames(np.ones((100, 4), np.float32), t, t)
    w.close()


@pytest.mark.slow
def test_piped_commands_print_no_control_characters(tmp_path):
    _session(tmp_path / "s.h5")
    make_dataset_folder(tmp_path / "data", participants=2, blocks=1)
    env = {k: v for k, v in os.environ.items() if k != "CI"}
    runs = [
        ["info", str(tmp_path / "s.h5")],
        ["devices"],
        ["ports"],
        ["train", "--data", str(tmp_path / "data"), "--model", "knn", "--preset", "tiny",
         "--eval", "lopo", "--out", str(tmp_path / "run"), "--cache-dir", str(tmp_path / "c")],
        ["evaluate", str(tmp_path / "run"), "--cache-dir", str(tmp_path / "c")],
    ]
    for argv in runs:
        proc = subprocess.run([sys.executable, "-m", "tactile_studio", *argv],
                              capture_output=True, text=True, env=env, timeout=120)
        assert proc.returncode == 0, proc.stderr
        for text in (proc.stdout, proc.stderr):
            assert not [c for c in text if not c.isprintable() and c != "\n"], (argv, text)
    assert "frames" in subprocess.run(
        [sys.executable, "-m", "tactile_studio", "info", str(tmp_path / "s.h5")],
        capture_output=True, text=True, env=env, timeout=60).stdout


def test_a_reader_that_goes_away_gets_no_traceback(tmp_path):
    # `tactile-studio compare A B | head -3`: the pipe closes while we still print
    read, write = os.pipe()
    os.close(read)
    try:
        proc = subprocess.run([sys.executable, "-m", "tactile_studio", "devices"],
                              stdout=write, stderr=subprocess.PIPE, text=True, timeout=60)
    finally:
        os.close(write)
    assert proc.returncode == 141 and proc.stderr == "", proc.stderr


def test_info_json_is_unchanged_json(tmp_path, capsys):
    _session(tmp_path / "s.h5")
    assert main(["info", str(tmp_path / "s.h5"), "--json"]) == 0
    text = capsys.readouterr().out
    summary = json.loads(text)
    assert text == json.dumps(summary, indent=2, default=str) + "\n"
    assert summary["frames"] == 100 and summary["metadata"]["participant"] == "P07"
