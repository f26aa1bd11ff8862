"""`python -m benchmarks NAME --option`: the options reach that benchmark."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _benchmarks(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "benchmarks", *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)


def test_options_go_to_the_named_benchmark():
    done = _benchmarks("population", "--help")  # before: ignored, the whole bench ran
    assert done.returncode == 0, done.stderr
    assert "--variance-only" in done.stdout


def test_options_with_several_benchmarks_are_refused_in_one_line():
    done = _benchmarks("bench_", "--help")
    assert done.returncode == 2
    assert done.stderr.strip().count("\n") == 0 and "go to one benchmark" in done.stderr
