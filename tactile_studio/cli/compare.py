"""``tactile-studio compare RUN_A RUN_B [--json]``: two runs on their shared test trials."""

from __future__ import annotations

import argparse

from tactile_studio.cli.json_output import print_json


def cmd_compare(args: argparse.Namespace) -> int:
    from tactile_studio.cli import tables
    from tactile_studio.learn.results.compare import compare_runs

    r = compare_runs(args.run_a, args.run_b)
    if args.json:
        print_json(r, indent=1)
        return 0
    # one table helper for both tables: columns fit the longest run name or participant
    tables.table(("", "run", "accuracy", "folder"),
                 [("A", r["name_a"], f"{100 * r['accuracy_a']:.1f}%", r["run_a"]),
                  ("B", r["name_b"], f"{100 * r['accuracy_b']:.1f}%", r["run_b"])],
                 right=("accuracy",))
    if r["n_matched"] < max(r["n_trials_a"], r["n_trials_b"]):  # a partial run, say
        print(f"accuracies over the {r['n_matched']} test trials both runs have "
              f"({r['name_a']}: {r['n_trials_a']}, {r['name_b']}: {r['n_trials_b']})")
    if r["config_difference"]:
        print("differ in: " + "; ".join(r["config_difference"]))
    tables.table(("participant", "A", "B", "B-A", "trials"),
                 [(p, f"{100 * v['accuracy_a']:.1f}", f"{100 * v['accuracy_b']:.1f}",
                   f"{100 * (v['accuracy_b'] - v['accuracy_a']):+.1f}", v["trials"])
                  for p, v in r["per_participant"].items()],
                 right=("A", "B", "B-A", "trials"))
    print(r["sentence"])
    for s in r.get("shots", [])[1:]:  # the few-shot curve: the same comparison at each K
        print(f"with {s['k']} shot(s) per gesture: {s['sentence']}")
    return 0


def register(subparsers) -> None:
    p = subparsers.add_parser("compare", help="compare two runs on their shared test trials "
                                              "(accuracies, Wilcoxon, McNemar)")
    p.add_argument("run_a", metavar="RUN_A")
    p.add_argument("run_b", metavar="RUN_B")
    p.add_argument("--json", action="store_true", help="print every number as JSON")
    p.set_defaults(func=cmd_compare)
