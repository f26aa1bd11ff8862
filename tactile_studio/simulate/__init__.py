"""The simulated tactile sensor (Qt-free, numpy only).

``SensorSimulator(...).step(n)`` gives raw frames with no threads or timing; the
``simulated`` device plugin (:mod:`tactile_studio.plugins.simulated`) paces it in real
time (or faster) for the acquisition engine. See docs/simulator.md.
"""

from tactile_studio.simulate.contact import Contacts, channel_points, stress_fields
from tactile_studio.simulate.gestures import (
    GESTURE_NAMES,
    GESTURES,
    IDLE,
    GestureModel,
    Style,
    TrialParams,
    canonical_gesture,
    gesture_model,
)
from tactile_studio.simulate.schedule import AUTO, PRESS, Schedule, Trial
from tactile_studio.simulate.simulator import FAULTS, SensorSimulator, SimConfig

__all__ = [
    "AUTO", "FAULTS", "GESTURES", "GESTURE_NAMES", "IDLE", "PRESS", "Contacts", "GestureModel",
    "Schedule", "SensorSimulator", "SimConfig", "Style", "Trial", "TrialParams",
    "canonical_gesture", "channel_points", "gesture_model", "stress_fields",
]
