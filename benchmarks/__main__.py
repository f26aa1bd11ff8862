"""Run every benchmarks/bench_*.py main() in turn (``python -m benchmarks [name ...]``);
``python -m benchmarks NAME --option ...`` hands the options to that one benchmark."""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import sys
import time
from pathlib import Path


def main(argv: list[str]) -> int:
    first_option = next((i for i, a in enumerate(argv) if a.startswith("-")), len(argv))
    wanted, options = argv[:first_option], argv[first_option:]
    names = sorted(m.name for m in pkgutil.iter_modules([str(Path(__file__).parent)])
                   if m.name.startswith("bench_"))
    if wanted:
        names = [n for n in names if any(a in n for a in wanted)]
    if options and len(names) != 1:
        print(f"benchmarks: options ({' '.join(options)}) go to one benchmark; "
              f"{' '.join(wanted) or 'no name'} matches {len(names)}", file=sys.stderr)
        return 2
    from benchmarks.machine import stamp

    for name in names:
        print(f"\n=== {name} === {stamp()}", flush=True)
        start = time.perf_counter()
        run = importlib.import_module(f"benchmarks.{name}").main
        # defaults, not this command line's benchmark names, for those that parse options
        # (a main(rows=100_000) takes its default: given [] it crashed, and `make bench`
        # stopped at bench_import)
        params = list(inspect.signature(run).parameters)
        if params[:1] == ["argv"]:
            run(options)
        elif options:
            print(f"benchmarks: {name} takes no options", file=sys.stderr)
            return 2
        else:
            run()
        print(f"--- {name} took {time.perf_counter() - start:.1f} s", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
