"""ShearSense CSV parse rate (rows/s) on generated 100k-row files, plus write and
full import (CSV -> session file) rates.

Two files: one as Tactile Studio writes it (integer counts) and one in the old
software's real format: every value quoted, counts written as decimals ("1491.0"),
labels as "114.0", a baseline row of means with long decimals, and a few malformed
rows (short rows and two numbers run together). Goal: >= 100,000 rows/s on the
real-format file (a real file is ~100k rows, ~150 MB).
Run: python -m benchmarks.bench_import [ROWS] (or python benchmarks/bench_import.py).
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from tactile_studio.storage.exchange import shearsense as ss
from tactile_studio.storage.exchange.importers import import_shearsense_file
from tactile_studio.storage.exchange.shearsense import (
    HEADER,
    read_shearsense_csv,
    write_shearsense_csv,
)


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


def real_format_csv(path: Path, rows: int, seed: int = 0) -> tuple[Path, int]:
    """A file as the old collection software wrote it; returns (path, malformed rows)."""
    rng = np.random.default_rng(seed)
    raw = rng.integers(20000, 40000, size=(rows, 180))
    times = 1.69e9 + np.arange(rows) / 44.0 + rng.uniform(0, 1e-3, rows)
    labels = np.zeros(rows, dtype=np.int64)
    for start in range(200, rows - 600, 600):
        labels[start:start + 500] = ord("r")
    counts = np.array([f'"{i}.0",'.encode() for i in range(65536)], dtype="S10")
    with open(path, "wb") as fh:
        fh.write((",".join(f'"{h}"' for h in HEADER) + "\n").encode())
        base = ",".join(f'"{float(v)!r}"' for v in raw[:50].mean(axis=0))
        fh.write(f'"0.0",{base},"0.0","0.0"\n'.encode())
        for i in range(0, rows, 4096):
            j = min(rows, i + 4096)
            pre = np.array([f'"{float(t)!r}",'.encode() for t in times[i:j]])
            suf = np.array([f'"{int(lab > 0)}.0","{lab}.0"\n'.encode() for lab in labels[i:j]])
            mats = [p.view(np.uint8).reshape(p.shape[0], -1)
                    for p in (pre, counts[raw[i:j]], suf)]
            m = np.concatenate(mats, axis=1)
            fh.write(m[m != 0].tobytes())
            if i // 4096 % 4 == 1:  # a few broken rows, as real files have
                fh.write(b'"1690000000.5","1491.0","1502.0"\n')
                fh.write(b",".join([b'"1690000000.6"'] + [b'"1491.0"'] * 100 + [b'"14911502.0"']
                                   + [b'"1491.0"'] * 79 + [b'"0.0"', b'"0.0"']) + b"\n")
    malformed = 2 * sum(1 for i in range(0, rows, 4096) if i // 4096 % 4 == 1)
    return path, malformed


def _parse_rate(path: Path, rows: int, label: str, digest: bool = False) -> None:
    best = cpu = float("inf")
    for _ in range(3):
        t0, c0 = time.perf_counter(), time.process_time()
        data = read_shearsense_csv(path, digest=digest)
        best = min(best, time.perf_counter() - t0)
        cpu = min(cpu, time.process_time() - c0)
    assert data.n_frames == rows, (data.n_frames, rows)
    print(f"  parse {label}: {rows / best:10.0f} rows/s wall, {rows / cpu:.0f} rows/s of CPU "
          f"time (best of 3; load average {os.getloadavg()[0]:.1f}; malformed "
          f"{data.malformed_by_kind or 'none'})")


def main(rows: int = 100_000) -> None:
    print(f"ShearSense CSV, {rows} rows x 183 quoted fields")
    with tempfile.TemporaryDirectory() as tmp:
        path = _file(Path(tmp), rows)
        _parse_rate(path, rows, "app export (integers)")
        real, bad = real_format_csv(Path(tmp) / "P02_real_FLAT.csv", rows)
        print(f"  real-format file: {real.stat().st_size / 1e6:.0f} MB, {bad} malformed rows")
        _parse_rate(real, rows, "real format (decimals)")
        _parse_rate(real, rows, "real format + SHA-256 of the file, as import reads it",
                    digest=True)
        small, _ = real_format_csv(Path(tmp) / "P03_small_FLAT.csv", 5000)
        ss.FAST_DECIMALS = False  # the per-field reference path, for comparison
        try:
            t0 = time.perf_counter()
            read_shearsense_csv(small)
            dt = time.perf_counter() - t0
        finally:
            ss.FAST_DECIMALS = True
        print(f"  parse real format, reference path (float() per decimal field): "
              f"{5000 / dt:10.0f} rows/s (5000 rows)")
        t0 = time.perf_counter()
        import_shearsense_file(path, Path(tmp) / "s.h5")
        dt = time.perf_counter() - t0
        print(f"  import to session: {rows / dt:10.0f} rows/s  ({dt:.2f} s)")
        t0 = time.perf_counter()
        import_shearsense_file(real, Path(tmp) / "r.h5")
        dt = time.perf_counter() - t0
        print(f"  import real format to session: {rows / dt:10.0f} rows/s  ({dt:.2f} s)")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 100_000)
