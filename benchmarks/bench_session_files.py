"""Session file size and load time against the old software's ShearSense CSV.

The CSV is generated in the real files' format: every value quoted, counts written as
decimals (``"1491.0"``), a millisecond-jittered Unix time, labelled 2 s runs. Counts
come from the simulated sensor scaled to the real files' ~1,500-count baselines (same
relative noise). The same frames are imported into a session file (compressed on close)
and, for comparison, written the pre-compression way (uncompressed).

"Load" means getting every frame and timestamp into memory: ``csv.reader`` over the CSV
(the old scripts' way, without even converting to numbers), our vectorised parser, and
opening the session and reading ``raw`` + ``device_time``.

Goal (issue 13): the session at least 10x smaller than the CSV and 20x faster to load.

The ratio depends on the counts: the old files' ~1,500-count baselines compress better
than the simulated sensor's own (22,000-36,000 counts, 20 counts of noise: more random
low bits). So a second figure: the simulator's frames as ``record`` writes them (gestures
on, compressed on close) against the same session exported with ``export --format
shearsense-csv`` (issue 47: "about 12x smaller" was quoted for such a file, which
measured 6.7x).
Run: python -m benchmarks session_files [ROWS]
"""

from __future__ import annotations

import csv
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from tactile_studio.sensor.layout import SHEARSENSE_6X6
from tactile_studio.simulate.simulator import SensorSimulator, SimConfig
from tactile_studio.storage import SessionFile, SessionWriter
from tactile_studio.storage.exchange.importers import import_shearsense_file
from tactile_studio.storage.exchange.shearsense import HEADER, read_shearsense_csv


def _frames(rows: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    sim = SensorSimulator(SimConfig(seed=3))
    raw = np.round(sim.step(rows).astype(np.float64) * 0.05).astype(np.uint16)
    rng = np.random.default_rng(0)
    times = np.round(1.69e9 + np.arange(rows) / 43.0 + rng.normal(0, 0.002, rows), 3)
    labels = np.zeros(rows, dtype=np.int64)
    for i, start in enumerate(range(200, rows - 100, 130)):
        labels[start:start + 86] = ord("abcdefghi"[i % 9])
    return raw, times, labels


def _write_csv(path: Path, raw: np.ndarray, times: np.ndarray, labels: np.ndarray) -> None:
    """The real files' text: '"1491.0",' per count, written in blocks."""
    table = np.array([f'"{i}.0",'.encode() for i in range(65536)], dtype="S10")
    baseline = raw[:100].mean(axis=0)
    touched = (raw < 0.97 * baseline).any(axis=1)
    with open(path, "wb") as fh:
        fh.write((",".join(f'"{h}"' for h in HEADER) + "\n").encode())
        fh.write(("\"0\"," + ",".join(f'"{float(v)!r}"' for v in baseline) + ',"0","0"\n').encode())
        for i in range(0, len(raw), 4096):
            j = min(len(raw), i + 4096)
            pre = np.array([f'"{float(t)!r}",'.encode() for t in times[i:j]])
            suf = np.array([f'"{int(a)}","{int(b)}"\n'.encode()
                            for a, b in zip(touched[i:j], labels[i:j])])
            mats = [p.view(np.uint8).reshape(p.shape[0], -1)
                    for p in (pre, table[raw[i:j]], suf)]
            m = np.concatenate(mats, axis=1)
            fh.write(m[m != 0].tobytes())


def _best(fn, repeat: int = 3) -> float:  # noqa: ANN001
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def _csv_reader_pass(path: Path) -> None:
    with open(path, newline="") as fh:
        for _row in csv.reader(fh):
            pass


def _load_session(path: Path) -> None:
    with SessionFile(path) as s:
        s.raw()
        s.column("device_time")


def own_counts(rows: int) -> None:
    """The simulator's own counts, written as a recording is, against its CSV export."""
    from tactile_studio.storage.exchange.exporters import export_shearsense_csv

    sim = SensorSimulator(SimConfig(seed=3))  # its demo gestures, its own counts
    raw = sim.step(rows)
    times = 1.69e9 + np.arange(rows) / 43.0
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        w = SessionWriter(folder / "rec.h5", SHEARSENSE_6X6, {"plugin": "bench"})
        w.append_frames(raw, times, times - times[0])
        w.close()  # compressed, as when a recording stops
        csv_path = export_shearsense_csv(folder / "rec.h5", folder)
        h5, csv_size = (folder / "rec.h5").stat().st_size, csv_path.stat().st_size
    print(f"  the simulated sensor's own counts, recorded then exported as ShearSense CSV: "
          f"CSV {csv_size / 1e6:.1f} MB | session {h5 / 1e6:.1f} MB "
          f"({csv_size / h5:.1f}x smaller)")


def main(rows: int = 100_000) -> None:
    raw, times, labels = _frames(rows)
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        csv_path = folder / "P01_bench_FLAT.csv"
        _write_csv(csv_path, raw, times, labels)
        new = import_shearsense_file(csv_path, folder / "new.h5")
        old = folder / "old.h5"
        with SessionFile(new) as s:
            back = s.raw()
        assert np.array_equal(back, raw), "the session must hold the CSV's counts exactly"
        w = SessionWriter(old, SHEARSENSE_6X6, {"plugin": "bench"})
        w.append_frames(raw, times, times)
        w.close(compress=False)
        sizes = {p: p.stat().st_size for p in (csv_path, old, new)}
        t_reader = _best(lambda: _csv_reader_pass(csv_path), 2)
        t_parse = _best(lambda: read_shearsense_csv(csv_path), 2)
        t_old = _best(lambda: _load_session(old))
        t_new = _best(lambda: _load_session(new))
    mb = 1e6
    print(f"{rows} frames x 180 channels (~{rows / 43 / 60:.0f} min at 43 Hz)")
    print(f"  size: CSV {sizes[csv_path] / mb:7.1f} MB | session uncompressed "
          f"{sizes[old] / mb:6.1f} MB ({sizes[csv_path] / sizes[old]:4.1f}x smaller) | "
          f"compressed {sizes[new] / mb:6.1f} MB ({sizes[csv_path] / sizes[new]:4.1f}x smaller)")
    print(f"  load: csv.reader pass {t_reader:6.2f} s | vectorised CSV parser {t_parse:6.2f} s")
    print(f"        session uncompressed {t_old * 1000:6.1f} ms ({t_reader / t_old:5.0f}x "
          f"faster than csv.reader) | compressed {t_new * 1000:6.1f} ms "
          f"({t_reader / t_new:5.0f}x faster than csv.reader, "
          f"{t_parse / t_new:4.1f}x faster than the vectorised parser)")
    print("  goal: >= 10x smaller and >= 20x faster than the CSV (best of 2-3 runs)")
    own_counts(rows)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 100_000)
