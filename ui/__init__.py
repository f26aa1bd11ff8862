"""Tactile Studio's Qt layer (PySide6 + pyqtgraph): widgets that present the core.

Widgets draw what ``tactile_studio`` computes and forward user intent to it; no stress
maths, file formats or training loops live here.
"""
