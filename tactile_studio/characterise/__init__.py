"""Instrumented characterisation: the paper's sequences driven through a stage and a
load cell, the analysis per taxel, and the report. See docs/characterisation.md."""

from tactile_studio.characterise.plan import DIRECTIONS, SEQUENCES, Plan
from tactile_studio.characterise.run import (
    CharacterisationRequest,
    RunControl,
    calibration_from,
    run_characterisation,
)

__all__ = ["DIRECTIONS", "SEQUENCES", "CharacterisationRequest", "Plan", "RunControl",
           "calibration_from", "run_characterisation"]
