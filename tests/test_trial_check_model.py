"""The model check end to end (issue 46, items 2, 5, 6): a tiny forest trained here on
virtual people checks a virtual participant who performs another gesture than the
prompted one in a share of trials (``--set mistakes=...``), headless and post hoc."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from cli_process import run_cli
from learn_fixtures import make_dataset_folder

from tactile_studio.learn.experiments.experiment import ExperimentConfig, run_experiment
from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.storage.format.trial_checks import DEFAULT_TOP_K
from tactile_studio.storage.format.trials import TrialRecord

EXE = str(Path(sys.executable).parent / "tactile-studio")


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    """A LOPO forest over four virtual people of the nine shear9 gestures (seconds)."""
    root = tmp_path_factory.mktemp("qc_model")
    make_dataset_folder(root / "data", participants=4, blocks=3)
    cfg = ExperimentConfig(data=[str(root / "data")], model="rf", evaluation="lopo",
                           preset="tiny", threads=1, device="cpu",
                           cache_dir=str(root / "cache"))
    run_experiment(cfg, root / "run")
    return root / "run"


def _collect(out: Path, *extra: str) -> tuple[subprocess.CompletedProcess, Path]:
    proc = run_cli(
        [EXE, "collect", "--protocol", "shear9", "--participant", "P07", "--device",
         "simulated", "--virtual-participant", "--blocks", "4", "--speed", "0", "--out",
         str(out), "--set", "difficulty=easy", "--set", "mistakes=0.25", *extra], timeout=300)
    assert proc.returncode == 0, proc.stderr
    return proc, Path(proc.stdout.strip().splitlines()[-1])


def _mistakes(trials: list[TrialRecord]) -> list[TrialRecord]:
    return [t for t in trials if t.performed and t.performed.split("; ")[0] != t.gesture]


def test_headless_collection_flags_the_virtual_participants_mistakes(run, tmp_path):
    proc, path = _collect(tmp_path / "on", "--qc-model", str(run))
    assert f"trial check: {run.name}/" in proc.stderr
    with SessionFile(path) as s:
        trials = [t for t in s.trials if t.block >= 0]
        meta = s.metadata["trial_check"]
    wrong = _mistakes(trials)
    assert len(wrong) >= 5, "the share of mistakes did not reach the file"
    caught = [t for t in wrong if "model_mismatch" in t.flags]
    assert len(caught) >= 0.9 * len(wrong), [(t.gesture, t.check) for t in wrong]
    honest = [t for t in trials if t not in wrong]
    assert sum("model_mismatch" in t.flags for t in honest) <= 0.25 * len(honest)
    assert meta["top_k"] == DEFAULT_TOP_K and meta["not_scored"] == []
    # the first block by the run's model, the rest by it personalised (on by default)
    assert {t.block: t.check["model"] for t in trials} == {
        0: meta["model"], **{b: f"{meta['model']}+9 own trials" for b in (1, 2, 3)}}
    for t in caught:  # the reason names what it looked like
        assert t.check["reason"].startswith("looks like ")
        assert t.gesture in t.check["reason"]


def test_without_the_check_no_mistake_is_flagged(tmp_path):
    _, path = _collect(tmp_path / "off")
    with SessionFile(path) as s:
        wrong = _mistakes([t for t in s.trials if t.block >= 0])
    assert wrong and not any("model_mismatch" in t.flags for t in wrong)
    assert not any(t.check for t in wrong)


def test_qc_checks_recorded_sessions_out_of_fold(run, tmp_path):
    data = run.parent / "data"
    proc = run_cli([EXE, "qc", str(data / "P01.h5"), str(data / "P02.h5"),
                    "--model", str(run), "--json"], timeout=300)
    assert proc.returncode == 0, proc.stderr
    rows = json.loads(proc.stdout)
    assert {r["participant"] for r in rows} == {"P01", "P02"}
    assert all(r["out_of_fold"] for r in rows)
    assert rows[0]["trial"] == 1  # numbered as the console numbers them
    assert set(rows[0]) >= {"file", "trial", "participant", "prompted", "predicted",
                            "p_prompted", "rank", "flags", "reasons"}
    # honest trials of easy virtual people: few flagged
    assert sum("model_mismatch" in r["flags"] for r in rows) <= 0.2 * len(rows)
    table = run_cli([EXE, "qc", str(data / "P01.h5"), "--model", str(run)], timeout=300)
    assert table.returncode == 0 and "trials flagged" in table.stderr
    assert "P01" in table.stdout


def test_qc_refuses_sessions_that_share_no_gesture_with_the_model(run, tmp_path):
    path = make_dataset_folder(tmp_path / "other", participants=1, blocks=1,
                               gestures=("tap", "slap"))[0]
    proc = run_cli([EXE, "qc", str(path), "--model", str(run)], timeout=300)
    assert proc.returncode == 1
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "share no gesture" in lines[0], proc.stderr


def _forced_protocol(folder: Path) -> Path:
    """shear9 with every gesture declared ``force = "natural"`` (and no images)."""
    from tactile_studio.storage.format.protocol_file import load_protocol

    folder.mkdir(parents=True, exist_ok=True)
    lines = ['name = "force9"', "trial_s = 2.0", "blocks = 5", "free_play_s = 0.0"]
    for g in load_protocol("shear9").gestures:
        lines += ["[[gestures]]", f"name = {json.dumps(g.name)}", f'key = "{g.key}"',
                  f"definition = {json.dumps(g.definition)}", 'force = "natural"']
    path = folder / "force9.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_light_and_off_centre_trials_are_flagged_by_the_signal_checks(tmp_path):
    proc = run_cli(
        [EXE, "collect", "--protocol", str(_forced_protocol(tmp_path / "p")), "--participant",
         "P01", "--device", "simulated", "--virtual-participant", "--speed", "0", "--out",
         str(tmp_path / "out"), "--set", "light=0.3", "--set", "off_centre=0.3", "--set",
         "difficulty=easy"], timeout=300)
    assert proc.returncode == 0, proc.stderr
    with SessionFile(Path(proc.stdout.strip().splitlines()[-1])) as s:
        trials = [t for t in s.trials if t.block >= 0]
    light = [t for t in trials if "; light" in t.performed]
    off = [t for t in trials if "off centre" in t.performed]
    assert len(light) >= 8 and len(off) >= 8
    # too light: no contact at all, or under the natural force's range
    assert sum(bool({"no_contact", "too_light"} & set(t.flags)) for t in light) \
        >= 0.85 * len(light)
    assert sum("off_centre" in t.flags or "no_contact" in t.flags for t in off) \
        >= 0.85 * len(off)
    honest = [t for t in trials if ";" not in t.performed]
    assert sum(bool(t.flags) for t in honest) <= 0.15 * len(honest)


def test_a_model_that_is_not_there_is_one_line_before_anything_is_recorded(tmp_path):
    for cmd in (["collect", "--protocol", "shear9", "--participant", "P01",
                 "--virtual-participant", "--out", str(tmp_path / "out"), "--qc-model"],
                ["qc", str(tmp_path / "none.h5"), "--model"]):
        proc = run_cli([EXE, *cmd, str(tmp_path / "no-run")], timeout=120)
        assert proc.returncode == 1
        assert proc.stderr.strip().splitlines() == [
            f"tactile-studio: error: {tmp_path / 'no-run'}: no such run folder or exported model"]
    assert not (tmp_path / "out").exists()


def test_an_exported_model_checks_with_its_own_fold(run, tmp_path):
    from tactile_studio.cli import main
    from tactile_studio.learn.deploy.trial_check import ModelTrialCheck

    assert main(["export-model", str(run), "--format", "onnx"]) == 0
    exported = sorted((run / "export").glob("*.onnx"))
    last = exported[-1]  # r0-P04.onnx: the fold that left P04 out
    check = ModelTrialCheck(last, participant="P01")
    assert check.model.record["test_participants"] == ["P04"] and not check.out_of_fold
    proc = run_cli([EXE, "qc", str(run.parent / "data" / "P02.h5"), "--model",
                    str(last), "--json"], timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert {r["model"] for r in json.loads(proc.stdout)} == {check.describe()["model"]}


def test_the_check_is_personalised_with_the_first_block(run, tmp_path):
    proc = run_cli(
        [EXE, "collect", "--protocol", "shear9", "--participant", "P08", "--device",
         "simulated", "--virtual-participant", "--blocks", "2", "--speed", "0", "--out",
         str(tmp_path), "--set", "difficulty=easy", "--qc-model", str(run),
         "--qc-personalise"], timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert "personalised with 9 trials of the first block" in proc.stderr
    with SessionFile(Path(proc.stdout.strip().splitlines()[-1])) as s:
        events = [e for e in s.events if e["kind"] == "trial_check_personalised"]
        models = {t.block: t.check["model"] for t in s.trials if t.block >= 0}
    assert len(events) == 1 and events[0]["trials"] == 9
    assert not models[0].endswith("own trials") and models[1].endswith("+9 own trials")
