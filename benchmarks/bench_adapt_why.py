"""Why does adapting a forest to each person pay on the simulator but not on people?

Issue 37: on the real recordings rf lost 1.7 points when each person's window features
were z-scored by their own statistics (``--adapt person``); on the recalibrated simulator
it gains ~3 (docs/learning/defaults.md). This draws the benchmark-shaped set (10 people,
14 gestures, one 12 s performance per gesture on flat and pillow, ``difficulty real``)
from the ``real`` population with one kind of between-person difference switched off,
and per variant scores a stand-in for ``train`` (the library's window features on 2 s
windows with half overlap, a 100-tree forest, each person left out against the other
nine, a performance = mean of its windows' probabilities) as trained and with
``generalise.person_standardised``:

* ``base``: the ``real`` population as shipped;
* ``no_style``: one force, tempo, size, place, drag direction and balance, one fingertip
  and one tremor for everyone (the per-person-per-gesture interpretations and kin
  blends kept);
* ``no_interp``: no per-person-per-gesture force, tempo, size, direction or blends
  (the person style kept);
* ``neither``: both off.

Measured (2 seeds): base +7.3, no_style +8.8, no_interp +11.8, neither -0.9: every
difference the simulator draws between people moves their features together across
gestures, which z-scoring undoes. The variants replace the base style draw
(``Style.from_seed``) for the data generation only, restored afterwards.

Run: .venv/bin/python benchmarks/bench_adapt_why.py [--variants base neither ...]
       [--seeds 0 1] [--keep DIR]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from learn_fixtures import make_dataset_folder  # noqa: E402
from sklearn.ensemble import RandomForestClassifier  # noqa: E402

import tactile_studio.simulate.population as population  # noqa: E402
from tactile_studio.learn.data.dataset import read_sessions  # noqa: E402
from tactile_studio.learn.data.features import feature_matrix  # noqa: E402
from tactile_studio.learn.data.windowing import WindowSpec, cut  # noqa: E402
from tactile_studio.learn.learners.generalise import person_standardised  # noqa: E402
from tactile_studio.simulate import GESTURE_NAMES  # noqa: E402
from tactile_studio.simulate.gestures import Style  # noqa: E402

EXTRA = ("tap", "slap", "scratch", "squeeze", "press")
SAME_STYLE = {"tempo": 1.0, "angle": 0.0, "force": 1.05, "offset_x": 0.0, "offset_y": 0.0,
              "size": 1.0, "jitter": 0.9}
SAME_PERSON = {"person_tempo": 0.0, "person_force": 0.0, "person_offset_mm": 0.0,
               "shear_gain": (0.48, 0.48), "fingers": (1.0,)}
NO_INTERP = {"interpret_force": 0.0, "interpret_tempo": 0.0, "interpret_size": 0.0,
             "interpret_angle": 0.0, "blend": 0.0}
VARIANTS = {"base": ({}, {}), "no_style": (SAME_STYLE, SAME_PERSON),
            "no_interp": ({}, NO_INTERP), "neither": (SAME_STYLE, {**SAME_PERSON, **NO_INTERP})}


def make_variant(folder: Path, variant: str) -> Path:
    """The set drawn from the ``real`` population with ``variant``'s differences off."""
    style_fix, pop_fix = VARIANTS[variant]
    original, real = Style.__dict__["from_seed"], population.POPULATIONS["real"]

    def from_seed(cls, seed: int) -> Style:  # the base draw, then the fixed fields
        return replace(original.__func__(cls, seed), **style_fix)

    Style.from_seed = classmethod(from_seed)
    population.POPULATIONS["real"] = replace(real, **pop_fix)
    population.person.cache_clear()
    try:
        make_dataset_folder(folder, participants=10, blocks=1, gestures=(*GESTURE_NAMES, *EXTRA),
                            difficulty="real", repeats=6, conditions=("FLAT", "PILLOW"),
                            first_style=101)
    finally:
        Style.from_seed = original
        population.POPULATIONS["real"] = real
        population.person.cache_clear()
    return folder


def window_features(folder: Path) -> tuple[np.ndarray, ...]:
    """(features, person, gesture, performance) of every 2 s window (half overlap)."""
    ds = read_sessions([str(folder)]).select(None)
    pieces, owner = cut(ds, WindowSpec(2.0, 0.5))
    x, _ = feature_matrix(pieces.trials, pieces.channel_names, pieces.rates)
    return x, pieces.participants, pieces.labels, owner


def lopo(x: np.ndarray, people: np.ndarray, y: np.ndarray, owner: np.ndarray,
         seed: int) -> dict[str, float]:
    """Each person's accuracy per performance, a forest trained on the others."""
    out = {}
    for p in np.unique(people):
        train, test = people != p, people == p
        forest = RandomForestClassifier(100, random_state=seed, n_jobs=1)
        probs = forest.fit(x[train], y[train]).predict_proba(x[test])
        hits = [forest.classes_[probs[owner[test] == o].mean(axis=0).argmax()]
                == y[test][owner[test] == o][0] for o in np.unique(owner[test])]
        out[str(p)] = float(np.mean(hits))
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--variants", nargs="+", default=list(VARIANTS), choices=list(VARIANTS))
    ap.add_argument("--seeds", nargs="+", type=int, default=[0])
    ap.add_argument("--keep", type=Path, default=None)
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        root = args.keep or Path(tmp)
        print(f"{'variant':10s} {'as trained':>10s} {'standardised':>12s} {'diff':>6s}  "
              "people up/down per seed")
        for variant in args.variants:
            start = time.perf_counter()
            folder = root / variant
            if not any(folder.glob("*.h5")):
                make_variant(folder, variant)
            x, people, y, owner = window_features(folder)
            z = person_standardised(x, people)
            plain, adapted, moves = [], [], []
            for seed in args.seeds:
                a, b = lopo(x, people, y, owner, seed), lopo(z, people, y, owner, seed)
                plain.append(np.mean(list(a.values())))
                adapted.append(np.mean(list(b.values())))
                moves.append(f"{sum(b[p] > a[p] for p in a)}/{sum(b[p] < a[p] for p in a)}")
            diff = 100 * (np.mean(adapted) - np.mean(plain))
            print(f"{variant:10s} {np.mean(plain):10.3f} {np.mean(adapted):12.3f} {diff:+6.1f}  "
                  f"{' '.join(moves)}  ({time.perf_counter() - start:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
