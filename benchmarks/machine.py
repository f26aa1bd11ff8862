"""The machine and date a benchmark's figures were measured on, printed with them.

The README and docs put this beside every figure they quote ("2026-11-28, 2-core AMD
EPYC VM, load 3.1"): a figure without it cannot be checked or compared, and this
machine is shared, so the load average at the time is part of the figure.
"""

from __future__ import annotations

import os
import platform
import time


def _cpu() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _memory_gb() -> float | None:
    try:
        with open("/proc/meminfo", encoding="utf-8") as fh:
            kb = int(next(ln for ln in fh if ln.startswith("MemTotal")).split()[1])
        return kb / 1024 / 1024
    except (OSError, StopIteration, ValueError):
        return None


def stamp() -> str:
    """"measured 2026-11-28 on AMD EPYC, 2 cores, 23 GB, load 3.1 (Python 3.11.7)"."""
    mem = _memory_gb()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return (f"measured {time.strftime('%Y-%m-%d')} on {_cpu()}, {os.cpu_count()} cores"
            + (f", {mem:.0f} GB" if mem else "") + f", load {load:.1f} "
            f"(Python {platform.python_version()})")


if __name__ == "__main__":
    print(stamp())
