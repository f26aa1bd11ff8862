"""Known weights and plates on the simulated sensor, for headless checks (``--auto``).

A weight of ``mass_g`` on a square contact of side ``contact_mm`` presses with
``m g / A``; a plate covers the whole array uniformly. The truth the checks must recover
is :func:`true_sensitivity` (per taxel, relative to the nominal calibration).
"""

from __future__ import annotations

import numpy as np

from tactile_studio.sensor.layout import CENTRE
from tactile_studio.sensor.wellness import parse_taxel, stress_kpa
from tactile_studio.simulate.schedule import Trial
from tactile_studio.simulate.simulator import SensorSimulator

UNIFORM_RADIUS_MM = 1000.0  # the simulator's "whole sensor" patch


def place_weight(sim: SensorSimulator, mass_g: float, taxel: str, contact_mm: float = 14.0,
                 duration_s: float = 60.0, at_frame: int | None = None) -> Trial:
    """Put a weight centred on ``taxel`` (e.g. 'B2') from ``at_frame`` (default: next)."""
    lay = sim.layout
    t = parse_taxel(lay, taxel)
    x, y = lay.taxel_centre_mm(*lay.taxel_rc(t))
    radius = contact_mm / np.sqrt(np.pi)  # a disc with the contact's area
    return sim.press(x, y, stress_kpa(mass_g, contact_mm), radius_mm=radius,
                     duration_s=duration_s, ramp_s=0.2, at_frame=at_frame)


def place_plate(sim: SensorSimulator, mass_g: float, plate_mm: float | None = None,
                duration_s: float = 60.0, at_frame: int | None = None) -> Trial:
    """A uniform plate of total ``mass_g`` over the array (side ``plate_mm``)."""
    lay = sim.layout
    side = plate_mm or lay.pitch_mm * max(lay.rows, lay.cols)
    return sim.press(0.0, 0.0, stress_kpa(mass_g, side), radius_mm=UNIFORM_RADIUS_MM,
                     duration_s=duration_s, ramp_s=0.2, at_frame=at_frame)


def lift(sim: SensorSimulator, trial: Trial, at_frame: int | None = None) -> None:
    """Take the weight of ``trial`` off from ``at_frame`` (default: the next frame)."""
    start = sim.frame if at_frame is None else int(at_frame)
    if start >= trial.stop:
        return
    sim.press(0.0, 0.0, 0.0, duration_s=(trial.stop - start) / sim.rate, ramp_s=0.0,
              at_frame=start)


def true_sensitivity(sim: SensorSimulator) -> np.ndarray:
    """Ground truth per taxel: centre-channel gain x taxel gain (1 = nominal)."""
    lay = sim.layout
    centre = np.arange(lay.n_taxels) * lay.channels_per_taxel + CENTRE
    return sim.gain[centre] * sim.taxel_gain
