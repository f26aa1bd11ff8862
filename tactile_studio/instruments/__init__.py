"""Instrument plugins beside devices: positioning stages and force references.

Contracts in :mod:`.contract`, discovery through the ``tactile_studio.stages`` and
``tactile_studio.forces`` entry-point groups (or ``register_stage`` / ``register_force``)
in :mod:`.registry`. The conformance checks for plugin authors (``check_stage``,
``check_force``) stream the sensor, so they live above acquisition, in
:mod:`tactile_studio.characterise`. See docs/characterisation.md.
"""

from tactile_studio.instruments.contract import (
    ForcePlugin,
    ForceSamples,
    InstrumentError,
    LabClock,
    SoftLimitError,
    StagePlugin,
)
from tactile_studio.instruments.registry import (
    available,
    create_force,
    create_stage,
    register_force,
    register_stage,
)

__all__ = [
    "ForcePlugin", "ForceSamples", "InstrumentError", "LabClock", "SoftLimitError",
    "StagePlugin", "available", "create_force", "create_stage", "register_force",
    "register_stage",
]
