"""The one way tests wait: poll a condition, never sleep a fixed time, always bounded."""

from __future__ import annotations

import time
from collections.abc import Callable


def wait_until(cond: Callable[[], bool], timeout: float = 15.0, step: float = 0.01,
               what: str | None = None) -> bool:
    """Poll ``cond`` until it is true (returns True) or ``timeout`` seconds pass (raises
    AssertionError naming what was awaited). Generous by default: a slow CI machine is
    not a failure, a condition that never comes is."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(step)
    if cond():
        return True
    raise AssertionError(f"timed out after {timeout:g} s waiting for "
                         f"{what or getattr(cond, '__name__', 'a condition')}")
