"""Simulated defects beyond gain changes (the gain-type faults live in the simulator)."""

from __future__ import annotations

import numpy as np

DELAMINATION_SHEAR = 0.35  # shear read per unit normal stress on a delaminated taxel


def add_delamination(load: np.ndarray, taxel: int, centre: np.ndarray, nc: int,
                     nt: int) -> None:
    """A skin peeled off one taxel: its top electrode slides sideways under a pure
    normal load, so the taxel reads shear proportional to the pressure (in place on the
    simulator's load array: normal per channel, then shear x, then shear y per taxel)."""
    normal = load[:, centre[taxel]]
    load[:, nc + taxel] += DELAMINATION_SHEAR * normal * np.cos(0.6)
    load[:, nc + nt + taxel] += DELAMINATION_SHEAR * normal * np.sin(0.6)
