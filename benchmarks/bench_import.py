"""ShearSense CSV parse rate (rows/s) on a generated 100k-row file, plus write and
full import (CSV -> session file) rates.

The goal is well over 50,000 rows/s for parsing (a real file is ~100k rows, ~150 MB).
Run: python -m benchmarks.bench_import [ROWS] (or python benchmarks/bench_import.py).
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from tactile_studio.storage.importers import import_shearsense_file
from tactile_studio.storage.shearsense import read_shearsense_csv, write_shearsense_csv


def _file(folder: Path, rows: int) -> Path:
    rng = np.random.default_rng(0)
    raw = rng.integers(20000, 40000, size=(rows, 180)).astype(np.uint16)
    times = 1.69e9 + np.arange(rows) / 43.0
    labels = np.zeros(rows, dtype=np.int64)
    for start in range(200, rows - 100, 300):
        labels[start:start + 86] = ord("r")
    t0 = time.perf_counter()
    path = write_shearsense_csv(folder / "P01_bench_FLAT.csv", raw, times, labels,
                                raw[:100].mean(axis=0))
    dt = time.perf_counter() - t0
    print(f"  write: {rows / dt:10.0f} rows/s  ({path.stat().st_size / 1e6:.0f} MB)")
    return path


def main(rows: int = 100_000) -> None:
    print(f"ShearSense CSV, {rows} rows x 183 quoted fields")
    with tempfile.TemporaryDirectory() as tmp:
        path = _file(Path(tmp), rows)
        best = cpu = float("inf")
        for _ in range(3):
            t0, c0 = time.perf_counter(), time.process_time()
            data = read_shearsense_csv(path)
            best = min(best, time.perf_counter() - t0)
            cpu = min(cpu, time.process_time() - c0)
        assert data.n_frames == rows
        print(f"  parse: {rows / best:10.0f} rows/s wall, {rows / cpu:.0f} rows/s of CPU time "
              f"(best of 3; load average {os.getloadavg()[0]:.1f})")
        t0 = time.perf_counter()
        import_shearsense_file(path, Path(tmp) / "s.h5")
        dt = time.perf_counter() - t0
        print(f"  import to session: {rows / dt:10.0f} rows/s  ({dt:.2f} s)")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 100_000)
