"""Training time as users meet it (issue 45 item 6): a network's LOPO round on the real
development set run as ``tactile-studio train`` runs it (a separate process, the train
panel's worker is the same ``run_experiment``), with the old thread settings and with
today's defaults, alternated so both meet the same neighbours.

- before: ``--threads 2`` (torch's default on this 2-core machine, what ``train`` used
  when ``--threads`` was not given) and OpenMP's default wait (threads spin at every
  barrier before they sleep);
- now: the defaults: one thread per training process (``experiment.TRAIN_THREADS``) and
  ``OMP_WAIT_POLICY=PASSIVE`` (set by ``tactile_studio/__init__.py``).

Printed per run: wall seconds, CPU seconds of the process (user + system) and their ratio.
On a loaded machine two spinning threads burn CPU that the other thread waits for
(FINDINGS of issue 45, section 7: 22x the CPU per step). Skips where the set is absent.

Run: nice -n 10 .venv/bin/python -m benchmarks.bench_train_threads [--model cnn1d]
     [--epochs 2] [--repeats 1]
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.real_data import dev_sessions, dev_set, skip_reason

SETTINGS = {
    "before (2 threads, spin-wait)": (["--threads", "2"], {"OMP_WAIT_POLICY": ""}),
    "now (defaults: 1 thread, passive)": ([], {}),
}


def one_round(model: str, sessions: Path, epochs: int, extra: list[str],
              env: dict[str, str], out: Path) -> tuple[float, float]:
    """(wall s, CPU s) of ``tactile-studio train --model MODEL`` (LOPO) in a new process."""
    clean = {k: v for k, v in os.environ.items()
             if k not in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS",
                          "OMP_WAIT_POLICY")}
    clean.update(env)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-m", "tactile_studio", "train", "--data", str(sessions),
         "--model", model, "--epochs", str(epochs), "--device", "cpu", "--out", str(out),
         *extra], capture_output=True, text=True, env=clean)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"train failed: {proc.stderr.strip().splitlines()[-1:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="bench_train_threads")
    ap.add_argument("--model", default="cnn1d")
    ap.add_argument("--epochs", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=1)
    args = ap.parse_args(argv or [])
    if dev_set() is None:
        print(f"skipped: {skip_reason()}")
        return 0
    sessions = dev_sessions(verbose=True)
    print(f"{args.model}, LOPO over the 5 real people, --epochs {args.epochs}, as `train` "
          f"runs it; load average before: {os.getloadavg()[0]:.1f}")
    results: dict[str, list[tuple[float, float]]] = {k: [] for k in SETTINGS}
    with tempfile.TemporaryDirectory(prefix="bench-threads-") as tmp:
        for r in range(args.repeats):
            for i, (name, (extra, env)) in enumerate(SETTINGS.items()):
                wall, cpu = one_round(args.model, sessions, args.epochs, extra, env,
                                      Path(tmp) / f"run{r}-{i}")
                results[name].append((wall, cpu))
                print(f"  {name:36s} wall {wall:6.1f} s  CPU {cpu:6.1f} s  "
                      f"(load {os.getloadavg()[0]:.1f})", flush=True)
    for name, rows in results.items():
        walls = sorted(w for w, _ in rows)
        cpus = sorted(c for _, c in rows)
        print(f"{name:36s} median wall {walls[len(walls) // 2]:6.1f} s, "
              f"CPU {cpus[len(cpus) // 2]:6.1f} s over {len(rows)} round(s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
