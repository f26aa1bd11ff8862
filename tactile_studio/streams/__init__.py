"""Lab Streaming Layer (LSL): frame and marker outlets over an acquisition engine.

Qt-free, and ``pylsl`` is imported only when a stream is actually opened, so the core
imports (and every other command works) on a machine without liblsl. See docs/lsl.md.
"""

from tactile_studio.streams.clock import ClockOffset, measure_offset
from tactile_studio.streams.lsl_lib import LslUnavailable, load_pylsl

__all__ = ["ClockOffset", "LslUnavailable", "load_pylsl", "measure_offset"]
