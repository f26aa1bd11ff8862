"""Instrumented characterisation: the paper's sequences driven through a stage and a
load cell, the analysis per taxel, and the report; and the conformance checks of stage
and force-reference plugins (``check_stage``, ``check_force``), which drive them the way
the procedure does. See docs/characterisation.md."""

from tactile_studio.characterise.instrument_checks import (
    InstrumentCheckError,
    check_force,
    check_stage,
)
from tactile_studio.characterise.plan import DIRECTIONS, SEQUENCES, Plan
from tactile_studio.characterise.procedure import (
    CharacterisationRequest,
    RunControl,
    calibration_from,
    run_characterisation,
)

__all__ = ["DIRECTIONS", "SEQUENCES", "CharacterisationRequest", "InstrumentCheckError", "Plan",
           "RunControl", "calibration_from", "check_force", "check_stage", "run_characterisation"]
