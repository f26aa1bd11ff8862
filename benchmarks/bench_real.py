"""Learning on real people (issue 45): the figure every learning decision is made on.

The development set (five real participants of the ShearSense study, 194 ~12 s labelled
performances, ``../shared/data/shearsense-dev``: benchmarks/real_data.py) is imported
once through ``import shearsense`` (the .csv.xz read directly; the import is timed into a
temporary folder every run, goal <= 15 s) and cached; then every chosen model family is
trained leave-one-participant-out through the product's own ``train`` path
(``run_experiment``, what ``tactile-studio train --data SESSIONS --model M`` runs) and
printed: accuracy per performance (mean of its 2 s windows) and per window, per person,
per gesture, the few-shot curve (``--shots``, the same test performances at every K) and
the wall time of each round. Skips with one line where the set is absent.

Five people give noisy folds: one performance of a person is 2-4 points of that person's
figure, and of 194 about 0.5 point overall. Decide with ``compare`` over rounds.

Run: nice -n 10 .venv/bin/python -m benchmarks.bench_real [--models rf,knn] [--shots 0,1,2]
     [--rounds 1] [--networks] [--epochs N] [--threads N]
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path
from typing import Any

from benchmarks.real_data import dev_files, dev_sessions, dev_set, import_files, skip_reason


def _pct(v: float | None) -> str:
    return "   -" if v is None else f"{v:.3f}"


def families(networks: bool) -> list[str]:
    """The registry's model families: the cheap (non-network) ones, and with ``networks``
    the torch models too (a network round on real data takes minutes)."""
    from tactile_studio.learn.learners.baselines import BASELINES
    from tactile_studio.learn.learners.families import available_models

    names = list(available_models())
    cheap = [n for n in names if n in BASELINES]
    return names if networks else cheap


def run(model: str, sessions: Path, shots: tuple[int, ...], rounds: int,
        epochs: int | None, threads: int | None, seed: int = 0) -> tuple[dict[str, Any], float]:
    """One ``train --model MODEL --data SESSIONS`` (LOPO): its metrics and wall seconds."""
    from tactile_studio.learn.experiments.experiment import ExperimentConfig, run_experiment
    from tactile_studio.learn.learners.generalise import ADAPT_AUTO

    # train's defaults (adapt auto, resolved by run_experiment as for the command)
    config = ExperimentConfig(data=[str(sessions)], model=model, evaluation="lopo",
                              rounds=rounds, epochs=epochs, seed=seed, shots=shots,
                              threads=threads, adapt=ADAPT_AUTO)
    start = time.perf_counter()
    result = run_experiment(config)
    return result.metrics, time.perf_counter() - start


def print_model(model: str, m: dict[str, Any], seconds: float, rounds: int) -> None:
    print(f"\n{model}: per performance {_pct(m.get('trial_accuracy'))}, per window "
          f"{_pct(m.get('accuracy'))} ({m.get('n_trials')} performances, {m.get('n')} windows; "
          f"adapt {m.get('adapt', 'none')}); {seconds:.0f} s wall for {rounds} round(s), "
          f"{seconds / rounds:.0f} s a round")
    print("  person   per perf.  per window  performances")
    for f in m["per_fold"]:
        print(f"  {','.join(f['test_participants']):7s}  {_pct(f.get('trial_accuracy')):>9s}  "
              f"{_pct(f.get('accuracy')):>10s}  {f.get('n_trials', '?'):>12}")
    per = m.get("trial_per_class_accuracy") or {}
    print("  per gesture (per performance): " + ", ".join(
        f"{g} {_pct(v)}" for g, v in sorted(per.items(), key=lambda kv: -(kv[1] or 0))))


def print_shots(model: str, m: dict[str, Any], seconds: float) -> None:
    by_person: dict[str, dict[int, float | None]] = {}
    for f in m["per_fold"]:
        by_person.setdefault(",".join(f["test_participants"]), {})[f.get("shots", 0)] = \
            f.get("trial_accuracy")
    ks = [s["k"] for s in m["shots"]]
    base = m["shots"][0].get("trial_accuracy")
    print(f"  few-shot (K labelled performances per gesture of the test person joined; "
          f"the same {m['shots'][0].get('n_trials')} test performances at every K; "
          f"{seconds:.0f} s wall):")
    for s in m["shots"]:
        gain = "" if s is m["shots"][0] or base is None else \
            f" ({100 * (s['trial_accuracy'] - base):+.1f})"
        print(f"    K={s['k']}: per performance {_pct(s.get('trial_accuracy'))}{gain}, "
              f"per window {_pct(s.get('accuracy'))}")
    print("    person   " + "  ".join(f"K={k:<4d}" for k in ks))
    for p, row in by_person.items():
        print(f"    {p:7s}  " + "  ".join(f"{_pct(row.get(k)):6s}" for k in ks))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="bench_real", description=__doc__.splitlines()[0])
    ap.add_argument("--models", default=None,
                    help="comma-separated model names (default: the cheap families)")
    ap.add_argument("--networks", action="store_true",
                    help="every family the registry lists, networks too (slow)")
    ap.add_argument("--shots", default="0,1,2", help="few-shot K values ('' for none)")
    ap.add_argument("--rounds", type=int, default=1)
    ap.add_argument("--epochs", type=int, default=None, help="networks' maximum epochs")
    ap.add_argument("--threads", type=int, default=None, help="torch threads (train's --threads)")
    ap.add_argument("--no-import-time", action="store_true",
                    help="skip timing a fresh import of the set")
    args = ap.parse_args(argv or [])
    folder = dev_set()
    if folder is None:
        print(f"skipped: {skip_reason()}")
        return 0
    files = dev_files(folder)
    if not args.no_import_time:
        with tempfile.TemporaryDirectory(prefix="bench-real-import-") as tmp:
            wall, cpu = import_files(files, Path(tmp))
        print(f"import shearsense of the {len(files)} compressed files: {wall:.1f} s wall, "
              f"{cpu:.1f} s CPU (goal <= 15 s; load average {os.getloadavg()[0]:.1f})")
    sessions = dev_sessions(verbose=True)
    models = args.models.split(",") if args.models else families(args.networks)
    shots = tuple(int(k) for k in args.shots.split(",") if k.strip())
    print(f"leave-one-participant-out over the development set ({folder}); models: "
          f"{', '.join(models)}")
    for model in models:
        m, seconds = run(model, sessions, (), args.rounds, args.epochs, args.threads)
        print_model(model, m, seconds, args.rounds)
        if shots:
            ms, seconds = run(model, sessions, shots, 1, args.epochs, args.threads)
            print_shots(model, ms, seconds)
    return 0


if __name__ == "__main__":
    import sys

    raise SystemExit(main(sys.argv[1:]))
