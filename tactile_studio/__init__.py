"""Tactile Studio: the Qt-free core (sensor maths, devices, sessions, learning).

Importing this package must never import PySide6 or pyqtgraph; the GUI lives in
``tactile_studio.ui`` and only presents what the core computes.
"""

__version__ = "0.1.0"
