"""How much of ``--adapt person`` does live calibration keep?

Evaluation with ``--adapt person`` adapts a model to each test person from their whole
session, the very trials it then predicts. Live, the model can only be calibrated on a
recording made before (Live inference > "Calibrate to person…", learn/window_model.py
``calibrate``). This benchmark replays that on finished lopo runs (e.g. the folders
``bench_generalise.py --adapt --keep DIR`` keeps): for every fold model and its test
person, the person's first K trials (in recording order) are the calibration recording and
the rest are predicted

* as trained (no calibration; not possible for rf/knn trained with --adapt),
* calibrated on the first K trials, for each K of ``--trials``,
* adapted to the very trials it predicts (as many as the largest K by default: does
  adaptation gain from the person, or from seeing the test trials themselves?),
* running: each trial predicted with the statistics of the person's last R trials up to
  and including it (``--running R``; what live inference's "Adapt as they touch" does,
  causal: nothing after the trial is used; ``--past-only``: the R trials before it),
* adapted to the whole session (the evaluation's figure, a ceiling for calibration),

all on the same held-out trials, pooled over every round and fold; each calibrated figure
is paired against "as trained" and against the whole session (Wilcoxon over participants,
McNemar over trials; learn/stats.py).

Run: .venv/bin/python benchmarks/bench_calibration.py RUN [RUN ...] [--trials 3 9 18]
       [--running 9] [--against RUN]   (e.g. the plain rf of the same data, as trained)
"""

from __future__ import annotations

import argparse
import re
import sys
import time
from pathlib import Path

import numpy as np

from tactile_studio.learn.evaluate import load_run_data
from tactile_studio.learn.stats import mcnemar_exact, wilcoxon_signed_rank
from tactile_studio.learn.window_model import WindowModel
from tactile_studio.sensor.layout import get_layout


def _order(uid: str) -> tuple[str, int]:
    """(session file, trial index) of a trial uid ``FILE#k``: recording order."""
    file, _, k = uid.rpartition("#")
    return file, int(re.sub(r"\D.*", "", k) or 0)


def replay(run: Path, ks: list[int], running: int = 0, past_only: bool = False
           ) -> tuple[str, dict[str, list[tuple[str, int, bool]]]]:
    """(model name, condition -> [(person, trial, right?)]) over every fold of ``run``."""
    config, _, records, ds, _, _ = load_run_data(run, device="cpu")
    layout, out = get_layout(ds.layout), {}
    for rec in records:
        (person,) = rec["test_participants"]
        own = sorted(np.flatnonzero(ds.participants == person), key=lambda i: _order(ds.uids[i]))
        rate = float(np.median(ds.rates[own]))
        rest = own[max(ks):]  # every condition predicts the same held-out trials
        windows = [ds.trials[i] for i in rest]

        def score(name: str, model: WindowModel) -> None:
            right = model.predict_windows(layout, windows, rate).argmax(axis=1) == ds.labels[rest]
            out.setdefault(name, []).extend(
                (f"{rec.get('round', 0)}:{person}", int(i), bool(r)) for i, r in zip(rest, right))

        model = WindowModel(run, person, rec.get("round", 0))
        if not model.needs_calibration:
            score("as trained", model)
        if not model.can_calibrate:  # rf/knn trained without --adapt
            continue
        for k in ks:
            model.calibrate(layout, [ds.trials[i] for i in own[:k]], rate, f"first {k}")
            score(f"first {k} trials", model)
        if running:
            right = []
            last = 0 if past_only else 1  # the predicted trial among its statistics?
            for p in range(max(ks), len(own)):
                recent = own[max(0, p - running + last):p + last]
                model.calibrate(layout, [ds.trials[i] for i in recent], rate, "running")
                probs = model.predict_windows(layout, [ds.trials[own[p]]], rate)[0]
                right.append(probs.argmax() == ds.labels[own[p]])
            out.setdefault(f"running {running}{' past' if past_only else ''}", []).extend(
                (f"{rec.get('round', 0)}:{person}", int(i), bool(r)) for i, r in zip(rest, right))
        model.calibrate(layout, windows, rate, "predicted")
        score("predicted trials", model)
        model.calibrate(layout, [ds.trials[i] for i in own], rate, "session")
        score("whole session", model)
    return config.model, out


def paired(a: list[tuple[str, int, bool]], b: list[tuple[str, int, bool]]) -> str:
    """A minus B in points, Wilcoxon over participants, McNemar over trials (matched by
    round, person and trial)."""
    right_b = {(p, i): r for p, i, r in b}
    a = [row for row in a if row[:2] in right_b]
    ra, rb = np.array([r for *_, r in a]), np.array([right_b[row[:2]] for row in a])
    people = sorted({p.split(":")[1] for p, *_ in a})
    who = np.array([p.split(":")[1] for p, *_ in a])
    acc_a = [ra[who == p].mean() for p in people]
    acc_b = [rb[who == p].mean() for p in people]
    _, p_w, _ = wilcoxon_signed_rank(np.array(acc_a), np.array(acc_b))
    p_m = mcnemar_exact(int((ra & ~rb).sum()), int((~ra & rb).sum()))
    return f"{100 * (ra.mean() - rb.mean()):+.1f} (p {p_w:.2g} / {p_m:.2g})"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", type=Path)
    ap.add_argument("--trials", nargs="+", type=int, default=[3, 9, 18],
                    help="calibration recordings: the person's first K trials")
    ap.add_argument("--against", type=Path, default=None, metavar="RUN",
                    help="also pair every figure with this run as trained (e.g. the plain "
                         "rf of the same data)")
    ap.add_argument("--running", type=int, default=0, metavar="R",
                    help="also predict each trial adapted to the person's last R trials "
                         "up to it (live's running adaptation)")
    ap.add_argument("--past-only", action="store_true",
                    help="running: the R trials before each predicted trial, without it")
    args = ap.parse_args(argv)
    ks = sorted(set(args.trials))
    against = replay(args.against, ks)[1]["as trained"] if args.against else None
    print(f"calibration on each test person's first {', '.join(map(str, ks))} trials; "
          f"the same trials after the first {max(ks)} predicted in every column; "
          "paired: points (Wilcoxon over participants / McNemar over trials)")
    for run in args.runs:
        t0 = time.perf_counter()
        name, out = replay(run, ks, args.running, args.past_only)
        first = next(iter(out.values()))
        print(f"\n{name} ({run}): {len(first)} predictions of "
              f"{len({p for p, *_ in first})} person-rounds, {time.perf_counter() - t0:.0f} s")
        for cond, rows in out.items():
            line = f"  {cond:>16}  {np.mean([r for *_, r in rows]):.3f}"
            if cond.startswith(("first", "predicted", "running")):
                if "as trained" in out:
                    line += f"   vs as trained {paired(rows, out['as trained'])}"
                line += f"   vs whole session {paired(rows, out['whole session'])}"
            if against is not None:
                line += f"   vs --against {paired(rows, against)}"
            print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
