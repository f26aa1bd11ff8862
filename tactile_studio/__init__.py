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
# OpenMP threads (torch, scikit-learn) that finished their share sleep instead of spinning
# (GNU OpenMP's default): on a shared or busy machine the spinning burns the CPU the
# other threads wait for (FINDINGS of issue 45: 22x the CPU per training step). Read when
# the OpenMP runtime loads, so set before torch is imported; a user's own setting wins.
_os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
