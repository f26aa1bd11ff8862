"""``tactile-studio check FILE...``: verify session files' invariants before trusting them.

Exit 0 when every file holds them; 5 (``CheckFailed``) naming how many files failed and
their first violations; 1 with one line when a file cannot be read at all.
"""

from __future__ import annotations

import argparse

from tactile_studio.cli.json_output import print_json
from tactile_studio.errors import CheckFailed, UserError
from tactile_studio.storage.format.session_check import CheckResult, check_file, summary_line


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "check", help="verify session files: clocks, trials, events, metadata, counters",
        description="Check that each session file's facts agree: device and host times "
                    "never go back within a recording segment, trials lie inside the "
                    "frames in order, block and session events sit around their trials, "
                    "metadata matches the frames, counters match the events. Exit 0 when "
                    "all hold, 5 naming the violations, 1 if a file cannot be read.")
    p.add_argument("file", nargs="+", help="session file(s) (.h5)")
    p.add_argument("--json", action="store_true",
                   help="print a list of {path, ok, violations} as JSON")
    p.set_defaults(func=cmd_check)


def cmd_check(args: argparse.Namespace) -> int:
    results: list[CheckResult] = []
    unreadable: list[str] = []
    for path in args.file:
        try:
            results.append(check_file(path))
        except UserError as exc:  # checked the others first; exit 1 at the end
            unreadable.append(str(exc))
            if args.json:
                results.append(CheckResult(str(path), [f"unreadable: {exc}"]))
    if args.json:
        print_json([r.to_dict() for r in results])
    else:
        for r in results:
            if r.ok:
                print(summary_line(r))
            else:
                print(f"{r.path}: {len(r.violations)} violation(s)")
                for v in r.violations:
                    print(f"  {v}")
    if unreadable:
        raise UserError(unreadable[0] + (f" (and {len(unreadable) - 1} more unreadable)"
                                         if len(unreadable) > 1 else ""))
    bad = [r for r in results if not r.ok]
    if bad:
        raise CheckFailed(f"{len(bad)} of {len(results)} session file(s) fail the check: "
                          + summary_line(bad[0]))
    return 0
