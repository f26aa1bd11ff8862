"""argparse types for numbers: every float option of the CLI is a finite number.

``float("nan")`` and ``float("inf")`` parse, and NaN slips past every ``<= 0`` check
(``record --seconds nan`` never stopped, ``collect --speed nan`` ran unpaced), so no option
uses ``type=float``: they use these (a test walks the whole parser to keep it so).
argparse turns the ``ArgumentTypeError`` into one usage line and exit status 2.
"""

from __future__ import annotations

import argparse
import math


def finite_float(text: str) -> float:
    """A float that is neither NaN nor ±inf."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    return value


def positive_float(text: str) -> float:
    """A finite float above zero (durations, rates, weights)."""
    value = finite_float(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"{text!r} must be above 0")
    return value


def non_negative_float(text: str) -> float:
    """A finite float of zero or more (a speed where 0 means "as fast as possible", a wait)."""
    value = finite_float(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"{text!r} must be 0 or more")
    return value
