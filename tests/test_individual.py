"""The individual-differences report: per-trial metrics, statsmodels GLMs on gesture,
participant and surface with effect sizes, per-participant shear/normal balance, figures
and an HTML page (virtual participants on a flat surface and on a pillow)."""

from __future__ import annotations

import csv

import matplotlib.image
import pytest
from learn_fixtures import make_dataset_folder

from tactile_studio.cli import main as cli_main
from tactile_studio.learn.experiments.individual import individual_report

GESTURES = ("Poke", "Heavy Pat", "Back & Forth Rub")


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("individual")
    for surface in ("FLAT", "PILLOW"):
        make_dataset_folder(root / "data" / surface, participants=3, blocks=2,
                            gestures=GESTURES, difficulty="real", condition=surface)
    return root


def test_report_models_gesture_participant_and_surface(data, tmp_path):
    result = individual_report([str(data / "data")], tmp_path / "r", str(data / "cache"))
    assert result["trials"] == 2 * 3 * 2 * len(GESTURES)
    eff = {(e["metric"], e["factor"]): e for e in result["effects"]}
    assert {f for _, f in eff} == {"gesture", "participant", "surface"}
    # contact area is mostly which gesture (a palm vs a fingertip), and the pillow spreads
    # the load: both clearly significant
    assert eff[("contact_area", "gesture")]["partial_eta2"] > 0.3
    assert eff[("contact_area", "gesture")]["p"] < 1e-3
    assert eff[("contact_area", "surface")]["p"] < 0.05
    for e in result["effects"]:
        assert 0 <= e["partial_eta2"] <= 1 and 0 <= e["p"] <= 1
    balance = {b["participant"]: b for b in result["balance"]}
    assert set(balance) == {"P01", "P02", "P03"}
    assert all(0 < b["q25"] <= b["median"] <= b["q75"] < 1 for b in balance.values())
    rows = list(csv.DictReader(open(tmp_path / "r" / "trials.csv")))
    assert {r["surface"] for r in rows} == {"FLAT", "PILLOW"}
    for name in ("effects.png", "balance.png", "metrics.png"):
        assert matplotlib.image.imread(tmp_path / "r" / name).shape[0] > 300
    page = (tmp_path / "r" / "index.html").read_text()
    assert "effects.png" in page and "P03" in page and "partial" in page


def test_cli_report_and_errors(data, tmp_path, capsys):
    code = cli_main(["report", "individual", "--data", str(data / "data" / "FLAT"),
                     "--out", str(tmp_path / "cli"), "--cache-dir", str(data / "cache")])
    assert code == 0 and "mostly" in capsys.readouterr().out
    one = tmp_path / "one"
    make_dataset_folder(one, participants=1, blocks=1, gestures=GESTURES)
    assert cli_main(["report", "individual", "--data", str(one), "--out",
                     str(tmp_path / "x"), "--cache-dir", str(data / "cache")]) == 1
    assert "at least 2 participants" in capsys.readouterr().err
