"""How much of ``--adapt person`` does live calibration keep?

Evaluation with ``--adapt person`` adapts a model to each test person from their whole
session, the very trials it then predicts. Live, the model can only be calibrated on a
recording made before (Live inference > "Calibrate to person…", learn/deploy/window_model.py
``calibrate``). This benchmark replays that on finished lopo runs (e.g. the folders
``bench_generalise.py --adapt --keep DIR`` keeps): for every fold model and its test
person, the person's first K trials (in recording order) are the calibration recording and
the rest are predicted

* as trained (no calibration; rf/knn trained with --adapt: standardised by the training
  people's pooled statistics, not possible for runs from before those were kept),
* calibrated on the first K trials, for each K of ``--trials``,
* adapted to the very trials it predicts (as many as the largest K by default: does
  adaptation gain from the person, or from seeing the test trials themselves?),
* running: each trial predicted with the statistics of the person's last R trials up to
  and including it (``--running R``; what live inference's "Adapt as they touch" does,
  causal: nothing after the trial is used; ``--past-only``: the R trials before it;
  ``--guard a0.34 v5``: also with a gesture-mix guard of live's RunningCalibration),
* adapted to the whole session (the evaluation's figure, a ceiling for calibration),

all on the same held-out trials, pooled over every round and fold; each calibrated figure
is paired against "as trained" and against the whole session (Wilcoxon over participants,
McNemar over trials; learn/evaluation/stats.py).

``--repeated N`` instead replays free play settling on one gesture (function
``repeated``), where unguarded running statistics normalise the gesture away; with
``--against RUN`` that run predicts the same windows as trained (e.g. the plain rf beside
an rf trained with --adapt).

Run: .venv/bin/python benchmarks/bench_calibration.py RUN [RUN ...] [--trials 3 9 18]
       [--running 9] [--guard a0.34 v5] [--against RUN]   (e.g. the plain rf, as trained)
     .venv/bin/python benchmarks/bench_calibration.py RUN --repeated 10 [--guard a0.34]
"""

from __future__ import annotations

import argparse
import re
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from tactile_studio.learn.deploy.live_inference import RunningCalibration
from tactile_studio.learn.deploy.window_model import WindowModel
from tactile_studio.learn.evaluation.stats import mcnemar_exact, wilcoxon_signed_rank
from tactile_studio.learn.learners.fused import display_name
from tactile_studio.learn.results.rescore import load_run_data
from tactile_studio.playback import SessionPlayback
from tactile_studio.sensor.layout import get_layout
from tactile_studio.simulate.population import DIFFICULTIES


def _order(uid: str) -> tuple[str, int]:
    """(session file, trial index) of a trial uid ``FILE#k``: recording order."""
    file, _, k = uid.rpartition("#")
    return file, int(re.sub(r"\D.*", "", k) or 0)


def run_touches(model: WindowModel, layout, stream: list[np.ndarray], rate: float,
                touches: int, guard: str = "", past_only: bool = False, start: int = 0
                ) -> list[int]:
    """Live's RunningCalibration over a ``stream`` of touches, each predicted (from
    ``start`` on) as it is kept: the predicted gestures. ``past_only``: with the statistics
    of the touches before it, without it (not live's rule)."""
    model.uncalibrate()
    running = RunningCalibration(model, touches=touches, minimum=touches - 1,
                                 variety=int(guard[1:]) if guard[:1] == "v" else 0,
                                 alike=float(guard[1:]) if guard[:1] == "a" else 1.0)
    out = []
    for p, window in enumerate(stream):
        if past_only and p >= start and running.count >= running.minimum:
            model.calibrate(layout, list(running.windows), rate, "their last touches")
        running.keep(layout, window, end=p << 20, rate=rate)
        if p < start:
            continue
        if not past_only:
            running.adapt_for(layout, window, rate, kept=True)
        out.append(int(model.predict_windows(layout, [window], rate)[0].argmax()))
    model.uncalibrate()
    return out


def replay(run: Path, ks: list[int], running: int = 0, past_only: bool = False,
           guards: tuple[str, ...] = ()) -> tuple[str, dict[str, list[tuple[str, int, bool]]]]:
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
            for guard in ("", *guards):
                right = run_touches(model, layout, [ds.trials[i] for i in own], rate, running,
                                    guard, past_only, len(own) - len(rest))
                name = f"running {running}{' past' if past_only else ''}" + \
                    (f" guard {guard}" if guard else "")
                out.setdefault(name, []).extend(
                    (f"{rec.get('round', 0)}:{person}", int(i), bool(r == ds.labels[i]))
                    for i, r in zip(rest, right))
        model.calibrate(layout, windows, rate, "predicted")
        score("predicted trials", model)
        model.calibrate(layout, [ds.trials[i] for i in own], rate, "session")
        score("whole session", model)
    return display_name(config.model, config.overrides), out


def repeated(run: Path, n: int, touches: int, guards: tuple[str, ...], folder: Path,
             difficulty: str = "real", against: Path | None = None
             ) -> dict[str, list[tuple[str, int, bool]]]:
    """Free play settling on one gesture: each round-0 fold's test person touches with the
    last ``touches`` trials of their session (varied), then performs one gesture ``n``
    times (a new session of the same virtual person, learn_fixtures' ``repeats``); those
    ``n`` windows are predicted as trained and adapting as they touch, unguarded and with
    each ``guards`` (see main); ``against``: also that run's fold model for the person, as
    trained (e.g. the plain rf of the same data, for runs that cannot predict as trained)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from learn_fixtures import write_participant

    config, _, records, ds, _, _ = load_run_data(run, device="cpu")
    layout, out = get_layout(ds.layout), {}
    for rec in [r for r in records if r.get("round", 0) == 0]:
        (person,) = rec["test_participants"]
        own = sorted(np.flatnonzero(ds.participants == person), key=lambda i: _order(ds.uids[i]))
        rate = float(np.median(ds.rates[own]))
        path = folder / f"{person}.h5"
        if not path.exists():
            write_participant(path, person, 100 + int(re.sub(r"\D", "", person)), blocks=1,
                              repeats=n, difficulty=difficulty, order=1)
        model = WindowModel(run, person, 0)
        plain = WindowModel(against, person, 0) if against is not None else None
        pb = SessionPlayback(path)
        try:
            base = pb.session.baseline(0)
            spans = [(model.labels.index(t.gesture), model.decode(layout, pb.raw[t.start:t.end],
                                                                  base)) for t in pb.trials]
        finally:
            pb.close()
        before = [ds.trials[i] for i in own[-touches:]]
        for g, frames in spans:
            per = frames.shape[1] // n
            windows = [frames[:, k * per:(k + 1) * per] for k in range(n)]
            conds = {}
            if against is not None:
                conds["--against"] = plain.predict_windows(layout, windows, rate).argmax(axis=1)
            if not model.needs_calibration:
                model.uncalibrate()
                conds["as trained"] = model.predict_windows(layout, windows, rate).argmax(axis=1)
            for guard in ("", *guards):
                conds[f"running {touches}" + (f" guard {guard}" if guard else "")] = \
                    run_touches(model, layout, before + windows, rate, touches, guard,
                                start=len(before))
            for name, got in conds.items():
                out.setdefault(name, []).extend((f"0:{person}", g * 1000 + k, bool(r == g))
                                                for k, r in enumerate(got))
    return out


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


def print_repeated(args: argparse.Namespace) -> int:
    touches = args.running or 9
    print(f"free play settling on one gesture: {touches} varied touches, then one gesture "
          f"{args.repeated} times, each of those predicted; paired: points (Wilcoxon over "
          "participants / McNemar over windows)")
    with tempfile.TemporaryDirectory() as folder:
        for run in args.runs:
            t0 = time.perf_counter()
            out = repeated(run, args.repeated, touches, tuple(args.guard), Path(folder),
                           args.difficulty, args.against)
            unguarded = out[f"running {touches}"]
            print(f"\n{run}: {len(unguarded)} windows of "
                  f"{len({p for p, *_ in unguarded})} people, {time.perf_counter() - t0:.0f} s")
            for cond, rows in out.items():
                line = f"  {cond:>16}  {np.mean([r for *_, r in rows]):.3f}"
                if "as trained" in out and cond != "as trained":
                    line += f"   vs as trained {paired(rows, out['as trained'])}"
                if "guard" in cond:
                    line += f"   vs unguarded {paired(rows, unguarded)}"
                if "--against" in out and cond != "--against":
                    line += f"   vs --against {paired(rows, out['--against'])}"
                print(line)
    return 0


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
    ap.add_argument("--guard", nargs="+", default=[], metavar="SPEC",
                    help="running: also with a guard of live's RunningCalibration: vK adapts "
                         "only while the last touches look like K or more different gestures "
                         "as trained, aS while no one gesture as trained is more than a share "
                         "S of them (e.g. v5 a0.34)")
    ap.add_argument("--repeated", type=int, default=0, metavar="N",
                    help="also replay free play settling on one gesture: varied touches, "
                         "then one gesture N times (round 0; with --running, default 9)")
    ap.add_argument("--difficulty", default="real", choices=DIFFICULTIES,
                    help="--repeated: the simulator population the runs' data was made at")
    args = ap.parse_args(argv)
    import torch

    torch.set_num_threads(1)  # two threads on the shared 2 cores stall beside other work
    if args.repeated:
        return print_repeated(args)
    ks = sorted(set(args.trials))
    against = replay(args.against, ks)[1]["as trained"] if args.against else None
    print(f"calibration on each test person's first {', '.join(map(str, ks))} trials; "
          f"the same trials after the first {max(ks)} predicted in every column; "
          "paired: points (Wilcoxon over participants / McNemar over trials)")
    for run in args.runs:
        t0 = time.perf_counter()
        name, out = replay(run, ks, args.running, args.past_only, tuple(args.guard))
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
