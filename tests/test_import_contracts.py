"""The core's import layers (pyproject.toml [tool.importlinter]) hold, and they would
catch a forbidden import: the same contracts fail on a copy of the core with one added."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LINT = Path(sys.executable).parent / "lint-imports"


def _lint(cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([str(LINT), "--config", str(cwd / "pyproject.toml")], cwd=cwd,
                          capture_output=True, text=True, timeout=240)


def test_the_layers_hold():
    result = _lint(ROOT)
    assert result.returncode == 0, result.stdout[-3000:]
    assert "Contracts: 2 kept, 0 broken." in result.stdout


def test_a_downward_import_breaks_the_contract(tmp_path):
    shutil.copytree(ROOT / "tactile_studio", tmp_path / "tactile_studio",
                    ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "pyproject.toml", tmp_path / "pyproject.toml")
    # the sensor maths reaching up into storage, and the core importing Qt
    (tmp_path / "tactile_studio" / "sensor" / "bad_upward.py").write_text(
        "import tactile_studio.storage.session\n")
    (tmp_path / "tactile_studio" / "learn" / "bad_qt.py").write_text(
        "import PySide6.QtCore\n")
    result = _lint(tmp_path)
    assert result.returncode != 0
    assert "tactile_studio.sensor.bad_upward -> tactile_studio.storage.session" in result.stdout
    assert "tactile_studio.learn.bad_qt -> PySide6" in result.stdout
