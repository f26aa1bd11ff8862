"""The trial check on real people (issue 46): how well a model of four people checks the
fifth, and how fast a verdict follows a trial's end.

The development set (benchmarks/real_data.py; five people, ~12 s labelled performances)
is trained leave-one-participant-out through ``train``'s own path (``run_experiment``,
default model rf, ``--model`` another family) into a temporary run folder; each person is
then checked with the fold that never saw them, through the product's
``ModelTrialCheck`` (what ``collect --qc-model`` and ``qc`` use). 10% of each person's
performances are relabelled to a random other gesture (``--seeds`` draws); the score is
p(prompted). Printed: ROC AUC (relabelled vs honest, mean and range over the draws) and
the share of relabelled / honest performances flagged at the default setting (top 3,
p < 0.10) and at a few others, per 12 s performance and per single 2 s trial (each
performance's first 2 s, what a collection trial is). ``--personalise``: each person's
check is first personalised with one performance per gesture of theirs (the few-shot
route, after a first block), which are then left out of the figures.

Latency: a real-time collection on the simulated sensor (43 Hz) with the check, one block
of shear9; the time from a trial's last frame being in to its verdict on the trial, and
the frames the engine dropped. Skips with one line where the set is absent.

Run: nice -n 10 .venv/bin/python -m benchmarks.bench_qc_real [--model rf] [--seeds 20]
     [--personalise] [--no-latency]
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

SETTINGS = ((3, 0.10), (3, 0.05), (2, 0.10), (1, 0.0))  # (top k, threshold); first: default


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
    """Every ok trial of the set: participant, gesture, raw counts, baseline, rate."""
    from tactile_studio.storage.format.session_file import SessionFile

    out = []
    for path in sorted(sessions.glob("*.h5")):
        with SessionFile(path) as s:
            who = str(s.metadata.get("participant") or path.stem)
            for t in s.trials:
                if t.get("status", "ok") != "ok" or not t.get("gesture"):
                    continue
                a, b = int(t["start_sample"]), min(int(t["end_sample"]), s.n_frames)
                if b - a < 8:
                    continue
                dev = s.column("device_time", a, b)
                span = float(dev[-1] - dev[0])
                out.append({"participant": who, "gesture": str(t["gesture"]),
                            "raw": s.raw(a, b), "baseline": s.baseline(a),
                            "rate": (b - a - 1) / span if span > 0 else 43.0,
                            "layout": s.layout})
    return out


def probabilities(run: Path, perfs: list[dict[str, Any]], personalise: bool
                  ) -> tuple[list[str], list[dict[str, Any]]]:
    """Each performance's probabilities (whole, and its first 2 s) by the fold that never
    saw its person; with ``personalise`` the first performance per gesture of each person
    personalises their check and is left out."""
    from tactile_studio.learn.deploy.trial_check import ModelTrialCheck

    scored = []
    labels: list[str] = []
    for who in sorted({p["participant"] for p in perfs}):
        check = ModelTrialCheck(run, participant=who)
        assert check.out_of_fold, f"{run} has no fold that left {who} out"
        labels = list(check.model.labels)
        mine = [p for p in perfs if p["participant"] == who and p["gesture"] in check.known]
        if personalise:
            shots, seen = [], set()
            for p in mine:
                if p["gesture"] not in seen:
                    seen.add(p["gesture"])
                    shots.append(p)
            check.personalise(mine[0]["layout"],
                              [(p["raw"], p["baseline"], p["gesture"]) for p in shots],
                              mine[0]["rate"])
            mine = [p for p in mine if not any(p is s for s in shots)]
        for p in mine:
            n2 = max(8, round(2.0 * p["rate"]))
            whole = check.probabilities(p["layout"], p["raw"], p["baseline"], p["rate"])
            first = check.probabilities(p["layout"], p["raw"][:n2], p["baseline"], p["rate"])
            scored.append({"participant": who, "gesture": p["gesture"], "whole": whole,
                           "first": first})
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
                i = event.trial["index"]
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


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", default="rf")
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--personalise", action="store_true")
    ap.add_argument("--no-latency", action="store_true")
    args = ap.parse_args(argv)
    if dev_set() is None:
        print(f"bench_qc_real: skipped: {skip_reason()}")
        return 0
    sessions = dev_sessions(verbose=True)
    with tempfile.TemporaryDirectory() as tmp:
        run = Path(tmp) / "run"
        seconds = train(sessions, args.model, run)
        print(f"trained {args.model} LOPO on the development set in {seconds:.0f} s")
        perfs = performances(sessions)
        labels, scored = probabilities(run, perfs, args.personalise)
        how = "personalised with one performance per gesture, " if args.personalise else ""
        print(f"checked out of fold ({how}{len(scored)} performances, {len(labels)} "
              f"gestures, 10% relabelled, {args.seeds} draws)")
        for unit, name in (("whole", "12 s performance"), ("first", "one 2 s trial")):
            f = figures(labels, scored, unit, args.seeds)
            mean, lo, hi = f["auc"]
            cells = "  ".join(f"top{k} p<{th:.2f}: {r[0]:.0%} / {r[1]:.0%}"
                              for (k, th), r in f["rates"].items())
            print(f"  {name:17s} AUC {mean:.3f} [{lo:.3f}-{hi:.3f}]  flagged relabelled / "
                  f"honest: {cells}")
        if not args.no_latency:
            lat = latency(run)
            ms = np.array(lat["latency_s"]) * 1000
            print(f"latency, trial end -> verdict on the trial (real-time collection, 43 Hz, "
                  f"{lat['trials']} trials, {lat['scored']} scored): median {np.median(ms):.0f} "
                  f"ms, max {ms.max():.0f} ms; frames dropped: {lat['dropped']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
