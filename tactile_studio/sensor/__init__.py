"""Sensor model: layouts, baselines, decoding raw counts to stresses, virtual taxels."""

from tactile_studio.sensor.decode import (
    StressFrames,
    compute_baseline,
    contact_map,
    decode,
    relative_change,
    touched,
)
from tactile_studio.sensor.layout import (
    LAYOUTS,
    SHEARSENSE_6X6,
    Calibration,
    Layout,
    get_layout,
    grid_layout,
)

__all__ = [
    "LAYOUTS", "SHEARSENSE_6X6", "Calibration", "Layout", "StressFrames", "compute_baseline",
    "contact_map", "decode", "get_layout", "grid_layout", "relative_change", "touched",
]
