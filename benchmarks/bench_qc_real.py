"""The trial check on real people (issue 46): how well a model of four people checks the
fifth, and how fast a verdict follows a trial's end.

The development set (benchmarks/real_data.py; five people, ~12 s labelled performances)
is trained leave-one-participant-out through ``train``'s own path (``run_experiment``;
train's default model, et adapted per person and surface; ``--model`` another family)
into a temporary run folder (``--run``: kept there, or reused); each person is then
checked with the fold that never saw them, through the product's ``ModelTrialCheck``
(what ``collect --qc-model`` and ``qc`` use). 10% of each person's performances are
relabelled to a random other gesture (``--seeds`` draws); the score is p(prompted).
Printed: ROC AUC (relabelled vs honest, mean and range over the draws) and the share of
relabelled / honest items flagged at the default setting and a few others, per 12 s
performance, per single 2 s trial (each performance's first 2 s: a collection trial
starts with the touch) and per 2 s window (every window of a performance on its own, the
research's unit), for each way of meeting the person (``--modes``, MODES): as trained
(the training people's pooled statistics); adapted to the person's own statistics on
each surface, from all their trials there (``qc``'s route; the collection's after a few
blocks) or from their first block only (one performance per gesture: the collection
just after its first block); and personalised with their first block (the few-shot
route), whose performances are then left out.

Latency: a real-time collection on the simulated sensor (43 Hz) with the check, one block
of shear9; the time from a trial's last frame being in to its verdict on the trial, and
the frames the engine dropped. Skips with one line where the set is absent.

Run: nice -n 10 .venv/bin/python -m benchmarks.bench_qc_real [--model et] [--seeds 20]
     [--modes as-trained,adapted,...] [--run DIR] [--save scores.npz] [--no-latency]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.real_data import dev_sessions, dev_set, skip_reason
from tactile_studio.protocol.runner_events import RunnerEvent, TrialEnded
from tactile_studio.storage.format.trial_checks import (
    DEFAULT_THRESHOLD,
    DEFAULT_TOP_K,
    rule_text,
)

# (top k (0: off), threshold); first: the default
SETTINGS = ((DEFAULT_TOP_K, DEFAULT_THRESHOLD), (0, 0.10), (0, 0.05), (3, 0.10), (1, 0.0))


def train(sessions: Path, model: str, out: Path) -> float:
    """LOPO ``train --model MODEL --data SESSIONS --out OUT`` with train's defaults."""
    from tactile_studio.learn.experiments.experiment import ExperimentConfig, run_experiment
    from tactile_studio.learn.learners.generalise import ADAPT_AUTO

    config = ExperimentConfig(data=[str(sessions)], model=model, evaluation="lopo",
                              adapt=ADAPT_AUTO)
    start = time.perf_counter()
    run_experiment(config, out)
    return time.perf_counter() - start


def performances(sessions: Path) -> list[dict[str, Any]]:
    """Every usable trial of the set (read as ``qc`` reads them): participant, surface
    (the session's condition), gesture, raw counts, baseline, rate."""
    from tactile_studio.cli.qc import checked_trials
    from tactile_studio.storage.format.session_file import SessionFile

    out = []
    for path in sorted(sessions.glob("*.h5")):
        with SessionFile(path) as s:
            who = str(s.metadata.get("participant") or path.stem)
            surface = str(s.metadata.get("condition") or "")
            out.extend({"participant": who, "surface": surface, "gesture": t.gesture,
                        "raw": f.raw, "baseline": f.baseline, "rate": f.rate,
                        "layout": s.layout}
                       for t, f in checked_trials(s) if t.usable and len(f.raw) >= 8)
    return out


# how each person's check meets them: (adapted to their own statistics, personalised)
MODES = {"as-trained": (None, False),
         "adapted": ("surface", False),            # all their trials on the surface (qc)
         "adapted-first": ("first", False),         # their first block's only (early live)
         "adapted+personalised": ("surface", True),
         "adapted-first+personalised": ("first", True),
         "personalised": (None, True)}


def first_block(mine: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One performance per gesture, the first of each (what a first block holds)."""
    shots, seen = [], set()
    for p in mine:
        if p["gesture"] not in seen:
            seen.add(p["gesture"])
            shots.append(p)
    return shots


def probabilities(run: Path, perfs: list[dict[str, Any]], mode: str
                  ) -> tuple[list[str], list[dict[str, Any]]]:
    """Each performance's probabilities (whole, and its first 2 s) by the fold that never
    saw its person, met as ``mode`` says (MODES): adapted to their statistics on each
    surface (all their trials there, or their first block's), personalised with their
    first block (one performance per gesture, then left out of the figures)."""
    from tactile_studio.learn.data.windowing import window_starts
    from tactile_studio.learn.deploy.trial_check import ModelTrialCheck

    adapt, personalise = MODES[mode]
    scored = []
    labels: list[str] = []
    for who in sorted({p["participant"] for p in perfs}):
        check = ModelTrialCheck(run, participant=who, adapt=adapt is not None)
        assert check.out_of_fold, f"{run} has no fold that left {who} out"
        assert adapt is None or check.adapts, f"{run}: its model does not adapt"
        labels = list(check.model.labels)
        mine = [p for p in perfs if p["participant"] == who and p["gesture"] in check.known]
        shots = first_block(mine)
        if personalise:
            check.personalise(mine[0]["layout"],
                              [(p["raw"], p["baseline"], p["gesture"]) for p in shots],
                              mine[0]["rate"])
        for surface in sorted({p["surface"] for p in mine}):
            here = [p for p in mine if p["surface"] == surface]
            if adapt is not None:
                sample = here if adapt == "surface" else first_block(here)
                check.adapt(here[0]["layout"], [(p["raw"], p["baseline"], p["gesture"])
                                                for p in sample], [p["rate"] for p in sample])
            for p in here:
                if personalise and any(p is s for s in shots):
                    continue
                frames = check.model.decode(p["layout"], p["raw"], p["baseline"])
                spec, n = check.model.spec, frames.shape[1]
                w = spec.frames(p["rate"])
                pieces = [frames[:, a:a + w] for a in window_starts(n, w, spec.stride(p["rate"]))
                          ] if n > spec.long_factor * w else [frames]  # as the run cut them
                every = check.model.predict_windows(p["layout"], pieces, p["rate"])
                scored.append({"participant": who, "gesture": p["gesture"],
                               "whole": every.mean(axis=0), "first": every[0],
                               "windows": every, "adapted_on": check.adapted_on})
    return labels, scored


def figures(labels: list[str], scored: list[dict[str, Any]], unit: str, seeds: int
            ) -> dict[str, Any]:
    """AUC and flag rates over ``seeds`` relabelling draws (10% of each person's)."""
    from sklearn.metrics import roc_auc_score

    from tactile_studio.storage.format.trial_checks import verdict

    aucs = []
    rates = {s: [[], []] for s in SETTINGS}  # setting -> [relabelled flags, honest flags]
    people = sorted({s["participant"] for s in scored})
    for seed in range(seeds):
        rng = np.random.default_rng(seed)
        y, score = [], []
        for who in people:
            mine = [s for s in scored if s["participant"] == who]
            n_wrong = max(1, round(0.1 * len(mine)))
            wrong = set(rng.choice(len(mine), n_wrong, replace=False).tolist())
            for i, s in enumerate(mine):
                prompted = s["gesture"]
                if i in wrong:
                    prompted = str(rng.choice([g for g in labels if g != s["gesture"]]))
                probs = s[unit]
                y.append(int(i in wrong))
                score.append(-float(probs[labels.index(prompted)]))
                for k, th in SETTINGS:
                    v = verdict(labels, probs, prompted, k, th)
                    rates[(k, th)][0 if i in wrong else 1].append(bool(v and v.flagged))
        aucs.append(roc_auc_score(y, score))
    return {"auc": (float(np.mean(aucs)), float(np.min(aucs)), float(np.max(aucs))),
            "rates": {s: (float(np.mean(r[0])), float(np.mean(r[1])))
                      for s, r in rates.items()}, "n": len(scored)}


def latency(run: Path, blocks: int = 1) -> dict[str, Any]:
    """A real-time collection (simulated sensor at 43 Hz, virtual participant) checked by
    the run's model: seconds from each trial's end to its verdict on the trial."""
    from tactile_studio.acquisition.open_stream import open_stream
    from tactile_studio.learn.deploy.trial_check import ModelTrialCheck
    from tactile_studio.plugins.simulated import SimulatedSensor
    from tactile_studio.protocol.collect import CollectionSettings, open_collection
    from tactile_studio.protocol.trial_runner import StreamClock
    from tactile_studio.protocol.virtual import VirtualParticipant
    from tactile_studio.storage.format.protocol_file import load_protocol

    check = ModelTrialCheck(run)
    seen: list[float] = []
    ended_at: dict[int, float] = {}
    protocol = load_protocol("shear9").with_overrides(blocks=blocks, free_play_s=0.0)
    device = SimulatedSensor(speed=1.0, gesture="idle", seed=1)
    engine = open_stream(device)
    with tempfile.TemporaryDirectory() as tmp:
        session = open_collection(CollectionSettings(protocol, "P90", tmp, trial_check=check),
                                  engine, clock=StreamClock(engine))
        runner = session.runner

        def on(event: RunnerEvent) -> None:
            if isinstance(event, TrialEnded):  # the verdict is on the trial written
                i = event.trial.index
                seen.append(time.perf_counter() - ended_at.get(i, time.perf_counter()))

        runner.add_listener(on)
        engine.start()
        vp = VirtualParticipant(runner, device, "P90")
        vp.prepare()
        try:
            while runner.state not in ("finished", "aborted"):
                cur = runner.current_trial
                if cur is not None and engine.frames >= cur["end"] \
                        and len(runner.records) not in ended_at:
                    ended_at[len(runner.records)] = time.perf_counter()
                runner.tick()
                vp.step()
                time.sleep(0.002)
            dropped = session.recorder.dropped + engine.counters()["missing_frames"]
        finally:
            session.close()
            engine.stop()
    return {"latency_s": seen, "dropped": dropped, "trials": len(seen),
            "scored": sum(1 for t in runner.records if t.check)}


UNITS = (("whole", "12 s performance"), ("first", "one 2 s trial"),
         ("windows", "every 2 s window"))


def report(labels: list[str], scored: list[dict[str, Any]], seeds: int) -> None:
    for unit, name in UNITS:
        items = scored
        if unit == "windows":  # each window on its own, as the research scored them
            items = [{**s, "windows": p} for s in scored for p in s["windows"]]
        f = figures(labels, items, unit, seeds)
        mean, lo, hi = f["auc"]
        cells = "  ".join(f"{rule_text(k, th)}: {r[0]:.0%} / {r[1]:.0%}"
                          for (k, th), r in f["rates"].items())
        print(f"  {name:17s} AUC {mean:.3f} [{lo:.3f}-{hi:.3f}]  flagged relabelled / "
              f"honest: {cells}", flush=True)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", default="et", help="the family trained (default: train's)")
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--modes", default="as-trained,adapted,adapted+personalised",
                    help=f"comma-separated, of {', '.join(MODES)}")
    ap.add_argument("--run", type=Path, help="a LOPO run of the set to reuse, or where "
                                             "to keep the one trained")
    ap.add_argument("--save", type=Path, help="write every mode's scores here (.npz)")
    ap.add_argument("--no-latency", action="store_true")
    args = ap.parse_args(argv)
    modes = args.modes.split(",")
    unknown = [m for m in modes if m not in MODES]
    if unknown:
        ap.error(f"unknown mode {', '.join(unknown)} (of {', '.join(MODES)})")
    if dev_set() is None:
        print(f"bench_qc_real: skipped: {skip_reason()}")
        return 0
    sessions = dev_sessions(verbose=True)
    with tempfile.TemporaryDirectory() as tmp:
        run = args.run or Path(tmp) / "run"
        if not (run / "config.json").is_file():
            seconds = train(sessions, args.model, run)
            print(f"trained {args.model} LOPO on the development set in {seconds:.0f} s")
        perfs = performances(sessions)
        saved: dict[str, np.ndarray] = {}
        for mode in modes:
            labels, scored = probabilities(run, perfs, mode)
            print(f"{mode}: checked out of fold ({len(scored)} performances, {len(labels)} "
                  f"gestures, 10% relabelled, {args.seeds} draws)", flush=True)
            report(labels, scored, args.seeds)
            for unit in ("whole", "first"):
                saved[f"{mode}/{unit}"] = np.array([s[unit] for s in scored])
            saved[f"{mode}/windows"] = np.concatenate([s["windows"] for s in scored])
            saved[f"{mode}/window_of"] = np.concatenate(
                [np.full(len(s["windows"]), i) for i, s in enumerate(scored)])
            saved[f"{mode}/gesture"] = np.array([labels.index(s["gesture"]) for s in scored])
            saved[f"{mode}/participant"] = np.array([s["participant"] for s in scored])
        if args.save:
            np.savez(args.save, labels=np.array(labels), **saved)
        if not args.no_latency:
            lat = latency(run)
            ms = np.array(lat["latency_s"]) * 1000
            print(f"latency, trial end -> verdict on the trial (real-time collection, 43 Hz, "
                  f"{lat['trials']} trials, {lat['scored']} scored): median {np.median(ms):.0f} "
                  f"ms, max {ms.max():.0f} ms; frames dropped: {lat['dropped']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
