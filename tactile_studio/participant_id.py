"""Participant IDs: one rule for sessions that are collected and sessions that are imported
(they end up in the same datasets, grouped by participant)."""

from __future__ import annotations

import re

from tactile_studio.errors import UserError

PARTICIPANT_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")


def check_participant(participant: str) -> str:
    """The ID without surrounding spaces, or a one-line UserError saying what is allowed."""
    p = participant.strip()
    if not PARTICIPANT_RE.match(p):
        raise UserError(f"bad participant id {participant!r}: use letters, digits, '_', '-' or "
                        "'.', e.g. P01")
    return p
