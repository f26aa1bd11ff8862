"""Writing the old collection software's ShearSense CSV (every value quoted, baseline
row first), fast: counts come from a precomputed text table, rows are joined as bytes."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.jobs import CancelToken, ProgressFn, no_progress
from tactile_studio.storage.exchange.shearsense_format import HEADER, MAX_COUNT, N_CHANNELS

_COUNT_TEXT: np.ndarray | None = None


def _count_text() -> np.ndarray:
    """'"v",' for every 16-bit count as fixed-width bytes (built once, ~0.5 MB)."""
    global _COUNT_TEXT
    if _COUNT_TEXT is None:
        _COUNT_TEXT = np.array([f'"{i}",'.encode() for i in range(MAX_COUNT + 1)], dtype="S8")
    return _COUNT_TEXT


def _number_text(v: float) -> str:
    return str(int(v)) if float(v).is_integer() else repr(float(v))


def _join_rows(parts: list[np.ndarray]) -> bytes:
    """Concatenate fixed-width byte columns per row, dropping the NUL padding."""
    mats = [p.view(np.uint8).reshape(p.shape[0], -1) for p in parts]
    m = np.concatenate(mats, axis=1)
    return m[m != 0].tobytes()


def write_shearsense_csv(path: str | os.PathLike, raw: np.ndarray, times: np.ndarray,
                         labels: np.ndarray, baseline: np.ndarray,
                         touched: np.ndarray | None = None, progress: ProgressFn | None = None,
                         cancel: CancelToken | None = None) -> Path:
    """Write frames in the old software's format (baseline row first).

    ``touched`` defaults to the old rule: any channel below 0.97 x its baseline.
    """
    path = Path(path)
    progress = progress or no_progress
    raw = np.asarray(raw)
    n = raw.shape[0]
    if raw.ndim != 2 or raw.shape[1] != N_CHANNELS:
        raise UserError(f"{path}: ShearSense CSV needs (N, 180) frames, got {raw.shape}")
    if raw.size and (raw.min() < 0 or raw.max() > MAX_COUNT):
        raise UserError(f"{path}: counts outside 0..65535 cannot be written as ShearSense CSV")
    baseline = np.asarray(baseline, dtype=np.float64)
    labels = np.asarray(labels).astype(np.int64)
    if touched is None:
        touched = (raw < 0.97 * baseline).any(axis=1)
    touched = np.asarray(touched).astype(bool)
    table = _count_text()
    with open(path, "wb") as fh:
        fh.write((",".join(f'"{h}"' for h in HEADER) + "\n").encode())
        base = ",".join(f'"{_number_text(v)}"' for v in baseline)
        fh.write(f'"0",{base},"0","0"\n'.encode())
        step = 4096
        for i in range(0, n, step):
            if cancel is not None:
                cancel.check()
            j = min(n, i + step)
            pre = np.array([f'"{float(t)!r}",'.encode() for t in times[i:j]])
            suf = np.array([f'"{int(t)}","{int(lab)}"\n'.encode()
                            for t, lab in zip(touched[i:j], labels[i:j])])
            fh.write(_join_rows([pre, table[raw[i:j].astype(np.int64)], suf]))
            progress(min(j / max(n, 1), 0.99), f"{path.name}: {j} of {n} frames")
    progress(1.0, f"{path.name}: {n} frames")
    return path
