"""Small old-software (ShearSense) CSVs with labelled runs, for import tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from tactile_studio.storage.exchange.shearsense import write_shearsense_csv


def labelled_csv(folder: Path, name: str, seed: int, keys: str = "rpz") -> Path:
    """A CSV with one 30-frame labelled run per character of ``keys`` (the key's code)
    after 30 unlabelled frames, 40 frames apart; ``keys`` "": nothing labelled."""
    rng = np.random.default_rng(seed)
    raw = rng.integers(30000, 30200, size=(60 + 40 * len(keys), 180)).astype(np.uint16)
    labels = np.zeros(len(raw), dtype=np.int64)
    for i, k in enumerate(keys):
        labels[30 + 40 * i: 60 + 40 * i] = ord(k)
    return write_shearsense_csv(folder / name, raw, 1.7e9 + np.arange(len(raw)) / 43, labels,
                                raw[:5].mean(axis=0))
