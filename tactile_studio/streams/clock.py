"""The offset between the host clock (``time.time()``, used for every frame's host_time)
and LSL's clock (``pylsl.local_clock()``, a monotonic clock).

``lsl_time = host_time + offset_s``. The offset is measured by bracketing one
``local_clock()`` read between two ``time.time()`` reads and keeping the tightest of
several tries; half the bracket is the uncertainty.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any


@dataclass(frozen=True)
class ClockOffset:
    """``lsl_time = host_time + offset_s`` (± ``uncertainty_s``), measured at ``host_time``."""

    offset_s: float
    uncertainty_s: float
    host_time: float
    lsl_time: float

    def to_lsl(self, host_time: Any) -> Any:
        """Host time(s) (float or numpy array) on LSL's clock."""
        return host_time + self.offset_s

    def to_host(self, lsl_time: Any) -> Any:
        return lsl_time - self.offset_s

    def as_dict(self) -> dict[str, float]:
        return asdict(self)


def measure_offset(local_clock: Callable[[], float], tries: int = 25,
                   host_clock: Callable[[], float] = time.time) -> ClockOffset:
    """The offset from ``host_clock`` to ``local_clock``, the tightest bracket of ``tries``."""
    best: tuple[float, float, float] | None = None
    for _ in range(max(1, tries)):
        t0 = host_clock()
        lsl = local_clock()
        t1 = host_clock()
        width = t1 - t0
        if best is None or width < best[0]:
            best = (width, (t0 + t1) / 2.0, lsl)
    assert best is not None
    width, host, lsl = best
    return ClockOffset(offset_s=lsl - host, uncertainty_s=width / 2.0, host_time=host,
                       lsl_time=lsl)
