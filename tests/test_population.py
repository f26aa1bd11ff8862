"""The simulator's difficulty: ``easy`` is the original sensor, ``real`` is calibrated to
the real recordings' population statistics and makes leave-one-participant-out as hard as
real people make it, ``people`` (the default, issue 45) splits its differences as real
people's are split; pillows spread and damp the load."""

from __future__ import annotations

import numpy as np
import pytest
from learn_fixtures import make_dataset_folder, make_virtual_population

from tactile_studio.errors import UserError
from tactile_studio.learn.data.dataset import read_sessions
from tactile_studio.learn.data.touch_stats import (
    REAL,
    pooled,
    population_stats,
    ratios_to_real,
    trial_stats,
)
from tactile_studio.learn.experiments.experiment import ExperimentConfig, run_experiment
from tactile_studio.sensor.decode import compute_baseline, decode
from tactile_studio.sensor.layout import SHEARSENSE_6X6
from tactile_studio.simulate import SensorSimulator, SimConfig, Style, TrialParams
from tactile_studio.simulate.population import (
    DIFFICULTIES,
    GESTURE_NAMES,
    gesture_force,
    person,
    population,
    trial_params,
)


def test_default_is_people_and_bad_settings_are_refused():
    assert SimConfig().difficulty == "people" and set(DIFFICULTIES) == {"easy", "real", "hard",
                                                                       "people"}
    with pytest.raises(UserError, match="difficulty"):
        SensorSimulator(difficulty="impossible")
    with pytest.raises(UserError, match="surface"):
        SensorSimulator(surface="carpet")


def test_easy_draws_exactly_the_original_parameters():
    a = trial_params(np.random.default_rng(5), "Poke", 42, 1.0, 1.0, "easy")
    b = TrialParams.draw(np.random.default_rng(5), Style.from_seed(42), 1.0, 1.0)
    assert a == b
    c = trial_params(np.random.default_rng(5), "Poke", 42, 1.0, 1.0, "real")
    assert c != b


def test_people_differ_more_at_higher_difficulty():
    def spread(level: str) -> float:
        forces = [person(s, population(level)).style.force for s in range(200)]
        return float(np.std(np.log(forces)))
    # real people differ from each other less than the first simulator's (issue 37)
    assert spread("real") < spread("hard")
    who = person(7, population("real"))
    assert who == person(7, population("real"))  # fixed by the style seed
    assert 1 <= who.fingers <= 3 and 0.3 <= who.shear_gain <= 0.6


def test_people_share_a_force_per_gesture_and_drag_each_gesture_their_own_way():
    """``people`` (issue 45): on the five real people gestures differ ~2x in force and a
    person's shear/normal balance depends on the gesture; ``real`` draws neither (its
    people stay bit for bit as the suite pins them)."""
    people, real = population("people"), population("real")
    factors = [gesture_force(g, people) for g in GESTURE_NAMES]
    assert np.std(np.log(factors)) > 0.3 and len(set(factors)) == len(factors)
    assert all(gesture_force(g, real) == 1.0 for g in GESTURE_NAMES)
    a, b = person(7, people), person(8, people)
    assert set(a.drag) == set(GESTURE_NAMES) and a.drag != b.drag
    assert person(7, real).drag == {}
    # the gesture's factor reaches the performance's force (the same draw otherwise:
    # what is left after the person's interpretation and the gesture's factor is equal)
    left = [trial_params(np.random.default_rng(1), g, 7, 1.0, 1.0, "people").force
            / a.interpretation[g][0] / gesture_force(g, people) for g in ("Poke", "Tickle")]
    assert left[0] == pytest.approx(left[1], rel=1e-9)


def _poke(**cfg) -> np.ndarray:
    sim = SensorSimulator(gesture="idle", seed=3, noise=0.0, style_seed=9, **cfg)
    base = compute_baseline(sim.step(100))
    sim.perform("Constant Touch", 2.0, at_frame=100)
    return decode(SHEARSENSE_6X6, sim.step(86), base).normal


def test_pillow_spreads_and_damps_the_load():
    flat, pillow = _poke(surface="flat"), _poke(surface="pillow")
    assert pillow.max() < 0.8 * flat.max()
    assert (pillow > 0.5).sum() > (flat > 0.5).sum()


@pytest.fixture(scope="module")
def cohorts(tmp_path_factory):
    root = tmp_path_factory.mktemp("population")
    out = {}
    for level in ("easy", "real", "people"):
        make_dataset_folder(root / level, participants=10, blocks=3, difficulty=level)
        out[level] = read_sessions([root / level]).select(None)
    return out


@pytest.mark.parametrize("level", ["real", "people"])
def test_real_population_statistics_match_the_recordings(cohorts, level):
    easy, real = (population_stats(ds.trials, ds.participants, ds.channel_names)
                  for ds in (cohorts["easy"], cohorts[level]))
    for name in ("taxels_above", "shear_normal"):  # easy is far off on these two ...
        target = REAL[name][0]
        assert abs(real[name]["median"] - target) < 0.5 * abs(easy[name]["median"] - target)
    for name in ("peak_normal_p90", "taxels_above", "peak_shear_p90", "shear_normal"):
        lo, hi = REAL[name][1], REAL[name][2]  # ... its median sits in the real IQR
        assert lo <= real[name]["median"] <= hi, (name, real[name])
    assert set(trial_stats(cohorts["real"].trials[0],
                           cohorts["real"].channel_names)) == set(REAL)


@pytest.mark.slow
def test_random_forest_lopo_drops_from_near_perfect_to_the_papers_range(cohorts):
    """`real` is held to the sensor paper's range; `people` (2 s trials of nine
    gestures) to what a forest does on 2 s windows of real people: 0.48 over the ten
    recorded people (issue 45), 0.40-0.70 allowing for nine gestures instead of 14."""
    acc = {}
    for level, ds in cohorts.items():
        cfg = ExperimentConfig(data=["unused"], model="rf", evaluation="lopo", preset="tiny")
        acc[level] = run_experiment(cfg, dataset=ds).metrics["trial_accuracy"]
    assert acc["easy"] > 0.9
    assert 0.5 <= acc["real"] <= 0.8, acc
    assert 0.4 <= acc["people"] <= 0.7, acc


@pytest.mark.slow
@pytest.mark.parametrize("level", ["real", "people"])
def test_virtual_people_vary_as_real_people_do(tmp_path, level):
    """Issue 37: median, IQR and between-person CV of every statistic within 25% of the
    real recordings', over four populations of ten virtual people (2 blocks of shear9's
    nine gestures each, as the issue measured). Before the recalibration the CVs of
    shear and of shear/normal were 1.5x and 3x the real ones. `people` (the default since
    issue 45) is held to the same bounds: its between-person spread follows the ten
    recorded people (the five of the development set put the person part at about twice
    that, but on 4 degrees of freedom), its gesture and within parts the development
    set's split.

    One exception, for `people`: the between-person CVs of peak shear and of
    shear/normal may reach 1.35x. A virtual person's median shear/normal over 18 trials
    of 2 s varies by repetition (within-person SD 0.21 log, 0.32 on people: 1.25 x 0.21 /
    sqrt(18) = 0.06) and by their own drag in each of nine gestures (person x gesture SD
    0.15 / sqrt(9) = 0.05): about 0.08 with no person part at all, where the ten real
    people's CV is 0.06 over 12 s performances of 14 gestures. Measured 1.24-1.32x
    over every setting tried (docs/simulator.md)."""
    stats = []
    for seed in range(4):
        make_virtual_population(tmp_path / str(seed), seed, difficulty=level)
        ds = read_sessions([tmp_path / str(seed)]).select(None)
        stats.append(population_stats(ds.trials, ds.participants, ds.channel_names))
    ratios = ratios_to_real(pooled(stats))
    assert set(ratios) == {"peak_normal_p90", "taxels_above", "peak_shear_p90", "shear_normal"}
    sampled = {("peak_shear_p90", "cv"), ("shear_normal", "cv")} if level == "people" else set()
    for name, r in ratios.items():
        assert set(r) == {"median", "iqr", "cv"}, name
        for what, value in r.items():
            top = 1.35 if (name, what) in sampled else 1.25
            assert 0.75 <= value <= top, (name, what, round(value, 2))


@pytest.mark.slow
def test_a_gestures_rhythm_tells_little_of_which_gesture_it_is_as_on_people(cohorts):
    """Issue 45: on the development set's people 5% of a 2 s window's dominant frequency
    is the gesture and 91% the moment; `real`'s metronome hand made it ~47% gesture.
    `people` paces and presses unevenly (docs/simulator.md: 16% and 65%; on this
    fixture 10% and 53%, `real` 33%)."""
    from tactile_studio.learn.data import variance_parts as vp

    share = {}
    for level in ("real", "people"):
        ds = cohorts[level]
        rows = [vp.stats_of(x, list(ds.channel_names), float(r))
                for x, r in zip(ds.trials, ds.rates)]
        parts = vp.parts_table(rows, list(ds.participants), list(ds.labels))["dominant_hz"]
        share[level] = vp.shares(parts)
    assert share["real"]["gesture"] > 0.25, share
    assert share["people"]["gesture"] < 0.2 and share["people"]["within"] > 0.45, share


def test_an_uneven_hand_is_the_same_rendered_in_pieces_or_whole():
    """The drifting pace and swelling press are functions of time within the trial, so a
    live stream (rendered chunk by chunk) and a file (whole) see the same performance."""
    from tactile_studio.simulate.population import render

    rng = np.random.default_rng(3)
    params = trial_params(rng, "Heavy Pat", 11, 1.0, 1.0, "people")
    t = np.arange(0, 2.0, 1 / 43)
    whole = render("Heavy Pat", t, 2.0, params, 11, "people", "flat")
    halves = [render("Heavy Pat", part, 2.0, params, 11, "people", "flat")
              for part in (t[:40], t[40:])]
    np.testing.assert_allclose(np.concatenate([h.load for h in halves]), whole.load)


def test_a_tickle_touches_from_its_start():
    """A key-started trial of a tickle sees contact in its first half second: the slowed
    `people` hand's first finger lands at once (TrialParams.onset), not up to a beat late
    (the console then flagged a virtual tickle 'no contact')."""
    from tactile_studio.simulate.population import render

    t = np.arange(0, 0.5, 1 / 43)
    for seed in range(20):
        params = trial_params(np.random.default_rng(seed), "Tickle", seed, 1.0, 1.0, "people")
        load = render("Tickle", t, 2.0, params, seed, "people", "flat").load.sum(axis=1)
        assert (load > 0.5).mean() > 0.5, seed  # 0.73 or more; 0.18 without the onset


@pytest.mark.parametrize("dur", [0.5, 1.0])
def test_an_uneven_hand_ends_its_performance_on_time(dur):
    """The drifting pace ends on time: every gesture of `people` has let go before its
    performance's end, as on an even hand. A clock left to drift ran up to 0.35 s late, and
    a key-started trial in the console then began during the last gesture's release."""
    from tactile_studio.simulate.population import render

    t = np.arange(0, dur + 0.6, 1 / 43)
    for gesture in GESTURE_NAMES:
        for seed in range(30):
            params = trial_params(np.random.default_rng(seed), gesture, seed, 1.0, 1.0,
                                  "people")
            load = render(gesture, t, dur, params, seed, "people", "flat").load.sum(axis=1)
            touched = t[load > 0.5]
            assert touched.size == 0 or touched[-1] < dur, (gesture, seed, touched[-1] - dur)
