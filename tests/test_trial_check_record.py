"""The trial checks on record (issue 46, item 4): ``info`` counts flags and decisions,
``check`` verifies the stored checks, ``export --format csv-trials`` and XDF carry them,
``train --exclude-flagged`` leaves flagged trials out (off by default, in config.json)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
import pyxdf
from check_fixtures import record_checked_session
from learn_fixtures import make_dataset_folder, trial_record, write_participant

from tactile_studio.cli import main
from tactile_studio.learn.experiments.experiment import ExperimentConfig, run_experiment
from tactile_studio.storage.exchange.xdf_export import export_xdf
from tactile_studio.storage.format.session_check import check_file
from tactile_studio.storage.format.session_file import SessionFile


@pytest.fixture(scope="module")
def recorded(tmp_path_factory) -> Path:
    return record_checked_session(tmp_path_factory.mktemp("checked"))


def test_info_counts_flags_checks_and_decisions(recorded, capsys):
    assert main(["info", str(recorded), "--json"]) == 0
    counts = json.loads(capsys.readouterr().out)["checks"]
    # (the performed trials' signal flags depend on where the stream was when they
    # were performed: only the checked ones are counted exactly)
    assert counts["by_flag"]["model_mismatch"] == 2 and counts["flagged"] >= 2
    assert counts["decisions"] == {"redo": 1, "keep": 1}
    assert counts["undecided"] == counts["flagged"] - 2
    assert counts["model_checked"] == 3  # the block's last gesture is not scored
    assert main(["info", str(recorded)]) == 0
    out = capsys.readouterr().out
    assert "decisions: redo 1, keep 1, undecided" in out and "3 checked by the model" in out
    assert "model_mismatch 2" in out


def test_check_passes_a_consistent_file(recorded):
    assert check_file(recorded).ok


@pytest.mark.damaged_files
def test_check_finds_stored_checks_that_disagree(tmp_path):
    bad = [
        {**trial_record(90, "Poke", 0, 20), "flags": ["model_mismatch"]},  # no check
        {**trial_record(91, "Poke", 20, 30), "decision": "maybe", "flags": ["no_contact"]},
        {**trial_record(92, "Poke", 30, 40), "check": {
            "model": "m", "p_prompted": 1.7, "rank": 1, "flagged": True, "top": [],
            "reason": ""}},
        {**trial_record(93, "Poke", 40, 42), "decision": "redo", "flags": ["no_contact"]},
    ]
    path = write_participant(tmp_path / "P01.h5", "P01", 101, gestures=("Poke",), blocks=1,
                             extra_trials=bad)
    text = "\n".join(check_file(path).violations)
    assert "trial 90: flagged model_mismatch without a stored check" in text
    assert "trial 91: decision 'maybe' is not redo or keep" in text
    assert "trial 92: check p_prompted 1.7 is not a probability" in text
    assert "trial 92: check and its model_mismatch flag disagree" in text
    assert "trial 93: decision redo but the trial was not redone" in text
    assert main(["check", str(path)]) == 5


def test_csv_trials_and_xdf_carry_the_checks(recorded, tmp_path):
    assert main(["export", str(recorded), "--format", "csv-trials", "--all-trials",
                 "--out", str(tmp_path)]) == 0
    (out,) = tmp_path.glob("*_trials.csv")
    rows = list(csv.DictReader(out.open(encoding="utf-8")))
    kept = [r for r in rows if r["decision"] == "keep"]
    assert len(kept) == 1 and "model_mismatch" in kept[0]["flags"]
    assert kept[0]["check_model"] == "contact-share" and kept[0]["predicted"] == "nothing"
    assert kept[0]["check_reason"].startswith("looks like nothing")
    assert [r["decision"] for r in rows].count("redo") == 1
    xdf = export_xdf(recorded, tmp_path)
    streams, _ = pyxdf.load_xdf(str(xdf))
    markers = [json.loads(m[0]) for s in streams if s["info"]["type"][0] == "Markers"
               for m in s["time_series"]]
    ends = [m for m in markers if m.get("kind") == "trial_end"]
    assert [m.get("decision") for m in ends].count("keep") == 1
    assert sum("check" in m for m in ends) == 3


def test_train_exclude_flagged_leaves_flagged_trials_out(tmp_path):
    gestures = ("Poke", "Twist")
    make_dataset_folder(tmp_path / "data", participants=2, blocks=2, gestures=gestures)
    # P01's first trial flagged: rewritten with the flag on record
    path = tmp_path / "data" / "P01.h5"
    with SessionFile(path) as s:
        first = s.trials[0]
    write_participant(path, "P01", 101, gestures, blocks=2, extra_trials=[
        {**first.to_dict(), "index": 0, "flags": ["no_contact"]}])

    def trained(name: str, exclude: bool) -> dict:
        cfg = ExperimentConfig(data=[str(tmp_path / "data")], model="rf", evaluation="lopo",
                               preset="tiny", threads=1, cache_dir=str(tmp_path / "cache"),
                               exclude_flagged=exclude)
        run_experiment(cfg, tmp_path / name)
        return json.loads((tmp_path / name / "config.json").read_text())

    all_in, without = trained("all", False), trained("clean", True)
    assert all_in["config"]["exclude_flagged"] is False
    assert without["config"]["exclude_flagged"] is True
    assert without["resolved"]["dataset"]["trials"] == all_in["resolved"]["dataset"]["trials"] - 1
