"""``tactile-studio report individual``: the individual-differences report."""

from __future__ import annotations

import argparse
from pathlib import Path

from tactile_studio.cli.learn import _Bar
from tactile_studio.jobs import CancelToken, ctrl_c_cancels


def cmd_report_individual(args: argparse.Namespace) -> int:
    from tactile_studio.learn.experiments.individual import individual_report

    token = CancelToken()
    bar = _Bar("report")
    try:
        with ctrl_c_cancels(token):
            result = individual_report(args.data, args.out, args.cache_dir, bar, token)
    finally:
        bar.close()
    strongest: dict[str, tuple[str, float]] = {}
    for e in result["effects"]:
        if e["partial_eta2"] > strongest.get(e["metric"], ("", -1.0))[1]:
            strongest[e["metric"]] = (e["factor"], e["partial_eta2"])
    print(f"individual differences: {result['trials']} trials")
    for metric, (factor, eta) in strongest.items():
        print(f"  {metric:16s} mostly {factor} (partial eta2 {eta:.2f})")
    print(f"report: {Path(args.out) / 'index.html'}")
    return 0


def register(subparsers) -> None:
    p = subparsers.add_parser("report", help="analysis reports over recorded sessions")
    sub = p.add_subparsers(dest="report", metavar="REPORT", required=True)
    q = sub.add_parser("individual", help="individual differences: GLM of touch metrics on "
                                          "gesture, participant and surface")
    q.add_argument("--data", nargs="+", required=True, metavar="PATH")
    q.add_argument("--out", required=True, metavar="DIR")
    q.add_argument("--cache-dir", default=None)
    q.set_defaults(func=cmd_report_individual)
