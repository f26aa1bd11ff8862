"""Run every benchmarks/bench_*.py main() in turn (``python -m benchmarks [name ...]``)."""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import sys
import time
from pathlib import Path


def main(argv: list[str]) -> int:
    names = sorted(m.name for m in pkgutil.iter_modules([str(Path(__file__).parent)])
                   if m.name.startswith("bench_"))
    if argv:
        names = [n for n in names if any(a in n for a in argv)]
    from benchmarks.machine import stamp

    for name in names:
        print(f"\n=== {name} === {stamp()}", flush=True)
        start = time.perf_counter()
        run = importlib.import_module(f"benchmarks.{name}").main
        # defaults, not this command line's benchmark names, for those that parse options
        # (a main(rows=100_000) takes its default: given [] it crashed, and `make bench`
        # stopped at bench_import)
        params = list(inspect.signature(run).parameters)
        run([]) if params[:1] == ["argv"] else run()
        print(f"--- {name} took {time.perf_counter() - start:.1f} s", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
