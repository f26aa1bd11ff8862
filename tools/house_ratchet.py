"""The house's figures that may only fall: `make lint` runs this.

Types are checked two ways. The public seams (the device, instrument, model and sink
contracts; job, engine, acquisition, runner and health events; trial records and fold
predictions: ``SEAMS``) pass ``mypy --strict`` with no error at all. Everything else is
ratcheted: the count of ``Any`` in function signatures (bare ``Any``, and any annotation
that contains it), of mypy errors over the whole house, of functions taking 10 or more
parameters and of functions over 80 lines are printed, and the check fails when one rises
above the figure recorded in ``house_ratchet.json``.
When a figure falls, ``--update`` records the lower one (it never records a higher one).

    python tools/house_ratchet.py            # print, fail (exit 1) on a rise
    python tools/house_ratchet.py --update   # record figures that fell
"""

from __future__ import annotations

import argparse
import ast
import json
import re
import subprocess
import sys
from collections.abc import Iterator, Sequence
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RECORD = Path(__file__).with_name("house_ratchet.json")
PACKAGES = ("tactile_studio", "ui", "plugins")
SEAMS = (
    "tactile_studio/devices/contract.py", "tactile_studio/devices/frame_stream.py",
    "tactile_studio/instruments/contract.py", "tactile_studio/learn/learners/contract.py",
    "tactile_studio/acquisition/file_sink.py", "tactile_studio/learn/experiments/job_events.py",
    "tactile_studio/protocol/trial_record.py", "tactile_studio/storage/format/trials.py",
    "tactile_studio/devices/engine_events.py", "tactile_studio/acquisition/events.py",
    "tactile_studio/protocol/runner_events.py", "tactile_studio/health/events.py",
    "tactile_studio/learn/learners/fold_predictions.py",
)
MANY_PARAMS = 10
LONG_LINES = 80
MYPY_FLAGS = ("--ignore-missing-imports", "--no-error-summary", "--hide-error-context")
_ANY = re.compile(r"\bAny\b")


def _functions(tree: ast.AST) -> Iterator[ast.FunctionDef | ast.AsyncFunctionDef]:
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            yield node


def _annotations(fn: ast.FunctionDef | ast.AsyncFunctionDef) -> list[ast.expr]:
    a = fn.args
    args = [*a.posonlyargs, *a.args, *a.kwonlyargs, *(x for x in (a.vararg, a.kwarg) if x)]
    found = [x.annotation for x in args if x.annotation is not None]
    return found + ([fn.returns] if fn.returns is not None else [])


def _parameters(fn: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    a = fn.args
    n = len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs)
    first = (a.posonlyargs + a.args)[:1]
    return n - 1 if first and first[0].arg in ("self", "cls") else n


def source_figures(root: Path = ROOT) -> dict[str, int]:
    """The figures read from the source alone (no type checker)."""
    bare = containing = many = long = 0
    for package in PACKAGES:
        for path in sorted((root / package).rglob("*.py")):
            for fn in _functions(ast.parse(path.read_text(encoding="utf-8"))):
                texts = [ast.unparse(x) for x in _annotations(fn)]
                bare += sum(1 for t in texts if t in ("Any", "typing.Any"))
                containing += sum(1 for t in texts if _ANY.search(t))
                many += _parameters(fn) >= MANY_PARAMS
                long += (fn.end_lineno or fn.lineno) - fn.lineno + 1 > LONG_LINES
    return {"any_bare": bare, "any_in_signatures": containing,
            f"functions_{MANY_PARAMS}_or_more_parameters": many,
            f"functions_over_{LONG_LINES}_lines": long}


def _mypy(args: Sequence[str], root: Path) -> list[str]:
    done = subprocess.run([sys.executable, "-m", "mypy", *MYPY_FLAGS, *args], cwd=root,
                          capture_output=True, text=True, timeout=900)
    if done.returncode not in (0, 1):  # 2: mypy itself failed (a crash, bad options)
        raise SystemExit(f"mypy failed: {done.stderr.strip() or done.stdout.strip()}")
    return [ln for ln in done.stdout.splitlines() if ": error: " in ln]


def seam_errors(root: Path = ROOT) -> list[str]:
    """mypy --strict over the public seams: every line an error (none allowed)."""
    return _mypy(["--strict", "--follow-imports=silent", *SEAMS], root)


def house_errors(root: Path = ROOT) -> int:
    """mypy's error count over the core (ui and plugins are installed beside it)."""
    return len(_mypy(["tactile_studio"], root))


def compare(now: dict[str, int], recorded: dict[str, int]) -> list[str]:
    """One line per figure that rose above its record."""
    return [f"{k}: {v} (recorded {recorded[k]}): a figure of the house rose; type it, "
            "split it or pass a settings object" for k, v in now.items()
            if k in recorded and v > recorded[k]]


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--update", action="store_true", help="record figures that fell")
    args = ap.parse_args(argv)
    strict = seam_errors()
    now = {**source_figures(), "mypy_errors": house_errors()}
    recorded = json.loads(RECORD.read_text()) if RECORD.exists() else dict(now)
    for k, v in now.items():
        print(f"{k:36s} {v:5d}  (recorded {recorded.get(k, v)})")
    print(f"{'seams under mypy --strict':36s} {len(SEAMS):5d} modules, {len(strict)} errors")
    for line in strict:
        print(line)
    rises = compare(now, recorded)
    for line in rises:
        print(f"house_ratchet: {line}", file=sys.stderr)
    if args.update or not RECORD.exists():
        lower = {k: min(v, recorded.get(k, v)) for k, v in now.items()}
        RECORD.write_text(json.dumps(lower, indent=1) + "\n")
    return 1 if strict or rises else 0


if __name__ == "__main__":
    sys.exit(main())
