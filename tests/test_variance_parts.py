"""The variance split the simulator is calibrated against (issue 45 item 5): known parts
drawn on purpose come back out, and an unbalanced table (some cells larger, a gesture one
person never did) is handled. Budget: < 1 s."""

from __future__ import annotations

import numpy as np
import pytest

from tactile_studio.learn.data.variance_parts import parts_table, shares, variance_parts


def draw(sd: dict[str, float], people=30, gestures=12, reps=(3, 6), seed=0):
    rng = np.random.default_rng(seed)
    a = rng.normal(0, sd["person"], people)
    b = rng.normal(0, sd["gesture"], gestures)
    ab = rng.normal(0, sd["person_x_gesture"], (people, gestures))
    v, p, g = [], [], []
    for i in range(people):
        for j in range(gestures):
            n = rng.integers(*reps)
            v += list(a[i] + b[j] + ab[i, j] + rng.normal(0, sd["within"], n))
            p += [i] * n
            g += [j] * n
    return np.array(v), np.array(p), np.array(g)


@pytest.mark.parametrize("sd", [
    {"person": 0.2, "gesture": 0.75, "person_x_gesture": 0.4, "within": 0.45},
    {"person": 0.0, "gesture": 0.3, "person_x_gesture": 0.0, "within": 0.7},
])
def test_known_parts_come_back(sd):
    got = variance_parts(*draw(sd))
    for part, want in sd.items():
        assert np.sqrt(got[part]) == pytest.approx(want, abs=0.12), (part, got)
    assert sum(shares(got).values()) == pytest.approx(1.0)


def test_gestures_not_everyone_did_are_left_out():
    v, p, g = draw({"person": 0.3, "gesture": 1.0, "person_x_gesture": 0.2, "within": 0.3},
                   people=6, gestures=5)
    only_some = g == 4
    drop = only_some & (p == 0)  # person 0 never did gesture 4
    got = variance_parts(v[~drop], p[~drop], g[~drop])
    assert got["G"] == 4 and got["P"] == 6


def test_parts_table_logs_skewed_statistics_and_skips_untouched_trials():
    rng = np.random.default_rng(1)
    rows, people, gestures = [], [], []
    for i in range(4):
        for j in range(3):
            for _ in range(4):
                rows.append({"peak_normal_p90": float(np.exp(j + rng.normal(0, 0.1))),
                             "taxels_above": 5.0, "peak_shear_p90": 1.0 + i,
                             "shear_normal": 0.3, "contact_s": 1.5,
                             "dominant_hz": 2.0 + rng.normal(), "contact": 0.9})
                people.append(i)
                gestures.append(j)
    rows.append({**rows[0], "contact": 0.0, "peak_normal_p90": 1e6})  # untouched: left out
    people.append(0)
    gestures.append(0)
    t = parts_table(rows, people, gestures)
    assert t["_kept"] == {"kept": 48, "of": 49}
    assert shares(t["peak_normal_p90"])["gesture"] > 0.95  # log: e^j is one step a gesture
    assert shares(t["peak_shear_p90"])["person"] > 0.95
