"""Tactile Studio: the Qt-free core (sensor maths, devices, sessions, learning).

Importing this package must never import PySide6 or pyqtgraph; the GUI lives in
``tactile_studio.ui`` and only presents what the core computes.
"""

import os as _os

__version__ = "0.1.0"

# onnxruntime (rf/knn models, export-model) otherwise keeps a telemetry device id and event
# store under the home folder (Microsoft DeveloperTools) and may upload it: a lab tool
# sends nothing anywhere. Set before onnxruntime loads, in every process that imports the
# app (CLI, GUI, sweep workers); a user's own setting wins.
_os.environ.setdefault("ORT_DISABLE_TELEMETRY", "1")
