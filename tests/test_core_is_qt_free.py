"""The core must not import Qt: scripts, the CLI and servers use it without a display.

Runs in a fresh interpreter, because this test session imports PySide6 elsewhere.
"""

from __future__ import annotations

import json
import subprocess
import sys

CHECK = r"""
import importlib, json, pkgutil, sys
import tactile_studio, tactile_studio.sensor, tactile_studio.devices, tactile_studio.storage
import tactile_studio.jobs, tactile_studio.cli, tactile_studio.live
import tactile_studio.plugins
from tactile_studio.cli import build_parser
build_parser()  # imports every CLI command module, including `gui`
plugins = []
for info in pkgutil.iter_modules(tactile_studio.plugins.__path__):
    try:
        importlib.import_module(f"tactile_studio.plugins.{info.name}")
        plugins.append(info.name)
    except ImportError as exc:  # an optional dependency missing is not our concern here
        if "PySide6" in str(exc) or "pyqtgraph" in str(exc):
            raise
qt = sorted(m for m in sys.modules if m.split(".")[0] in {"PySide6", "shiboken6", "pyqtgraph"}
            or m.startswith("tactile_studio.ui"))
print(json.dumps({"qt": qt, "plugins": plugins}))
"""


def test_importing_the_core_and_plugins_does_not_import_qt():
    out = subprocess.run([sys.executable, "-c", CHECK], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    result = json.loads(out.stdout.strip().splitlines()[-1])
    assert result["qt"] == [], f"Qt imported by the core: {result['qt'][:5]}"
    assert "simulated" in result["plugins"]
