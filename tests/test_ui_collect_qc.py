"""The console's trial check with a real model: the setup takes a QC model (a run folder
or a model exported from one), says which of the protocol's gestures it does not score,
remembers it per study with its top-k and threshold, and the session scores each trial
of a gesture the model knows (the verdict on the trial, the model in the metadata).

A tiny rf run (leave-one-participant-out over two simulated people, Poke and Twist
only; ~8 s) stands for a study's earlier participants; the mini3 protocol also has
Tickle, which the model does not know.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from console_helpers import fill_setup
from learn_fixtures import make_dataset_folder
from PySide6.QtCore import QSettings, Qt
from PySide6.QtWidgets import QFileDialog
from test_ui_collect import (  # noqa: F401 (env)
    WAIT_MS,
    continue_after_break,
    do_trial,
    env,
    make_console,
    snap,
)

from tactile_studio.learn.experiments.experiment import ExperimentConfig, run_experiment
from tactile_studio.learn.learners.generalise import ADAPT_AUTO
from tactile_studio.protocol.runner_events import CheckPersonalised
from tactile_studio.protocol.snapshot import State
from tactile_studio.storage.format.session_file import SessionFile
from tactile_studio.storage.format.trial_checks import DEFAULT_THRESHOLD, DEFAULT_TOP_K
from tactile_studio.ui.collect.qc_setup import DIALOG_KIND
from tactile_studio.ui.collect.setup import CollectSetup
from tactile_studio.ui.file_dialogs import start_folder


@pytest.fixture(scope="module")
def qc_run(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("qc")
    make_dataset_folder(root / "data", participants=2, blocks=2, gestures=("Poke", "Twist"))
    cfg = ExperimentConfig(data=[str(root / "data")], model="rf", evaluation="lopo",
                           threads=1, cache_dir=str(root / "cache"))
    run_experiment(cfg, root / "run")
    return root / "run"


@pytest.fixture(scope="module")
def qc_run3(tmp_path_factory) -> Path:
    """A run that knows all of mini3's gestures, on its 0.5 s trials (96% out of fold)."""
    root = tmp_path_factory.mktemp("qc3")
    make_dataset_folder(root / "data", participants=3, blocks=3,
                        gestures=("Poke", "Twist", "Tickle"), trial_s=0.5)
    cfg = ExperimentConfig(data=[str(root / "data")], model="rf", evaluation="lopo",
                           threads=1, cache_dir=str(root / "cache"))
    run_experiment(cfg, root / "run")
    return root / "run"


@pytest.fixture(scope="module")
def qc_run3_adapted(tmp_path_factory) -> Path:
    """train's default model (extra-trees, adapted per person and surface) on mini3's
    gestures and 0.5 s trials."""
    root = tmp_path_factory.mktemp("qc3a")
    make_dataset_folder(root / "data", participants=3, blocks=3,
                        gestures=("Poke", "Twist", "Tickle"), trial_s=0.5)
    cfg = ExperimentConfig(data=[str(root / "data")], model="et", evaluation="lopo",
                           adapt=ADAPT_AUTO, preset="tiny", threads=1,
                           cache_dir=str(root / "cache"))
    run_experiment(cfg, root / "run")
    return root / "run"


def choose_run(qtbot, setup: CollectSetup, run: Path, monkeypatch) -> None:
    """The "Run folder..." button and its dialog, as the experimenter picks the run."""
    monkeypatch.setattr(QFileDialog, "getExistingDirectory",
                        staticmethod(lambda *a, **k: str(run)))
    qtbot.mouseClick(setup.qc.run_button, Qt.MouseButton.LeftButton)


def two_blocks(qtbot, console, fitted_first: bool = False) -> Path:
    """Start the session set up and perform its two blocks (flagged trials kept); the
    session's file once it is closed. ``fitted_first``: block 1 starts once the check's
    personalisation is in (it runs on a copy beside the scoring, however long it takes)."""
    s = console.setup
    qtbot.mouseClick(s.start_button, Qt.MouseButton.LeftButton)
    assert s.error.text() == "" and console.stack.currentIndex() == 1
    path = console.session.path
    fitted: list[CheckPersonalised] = []
    console.session.runner.add_listener(
        lambda e: fitted.append(e) if isinstance(e, CheckPersonalised) else None)
    qtbot.mouseClick(console.buttons["primary"], Qt.MouseButton.LeftButton)
    qtbot.waitUntil(lambda: snap(console).state == State.WAITING, timeout=WAIT_MS)
    for block in range(2):
        if block:
            continue_after_break(qtbot, console)
            if fitted_first:  # the fit starts as the block does
                qtbot.waitUntil(lambda: bool(fitted), timeout=WAIT_MS)
        for _ in [x for x in snap(console).gestures if not x.done]:
            nxt = snap(console)
            g = next(x for x in nxt.gestures if x.name == nxt.prompted)
            do_trial(qtbot, console, g.name, g.key)
            if console.redo_banner.isVisible():  # flagged (model or signal): kept
                qtbot.mouseClick(console.redo_banner.keep, Qt.MouseButton.LeftButton)
    qtbot.waitUntil(lambda: console.session is None, timeout=WAIT_MS)
    return path


def test_the_setup_takes_a_qc_model_says_what_it_scores_and_remembers_it(
        qtbot, env, qc_run, monkeypatch, tmp_path):  # noqa: F811 (env)
    proto, _ = env
    settings = QSettings(str(tmp_path / "settings.ini"), QSettings.Format.IniFormat)
    setup = CollectSetup(settings)
    qtbot.addWidget(setup)
    setup.set_protocol_file(str(proto))
    qc = setup.qc
    assert qc.path.text() == "" and "signal is still checked" in qc.info.text()
    assert (qc.top_k.value(), qc.threshold.value()) == (DEFAULT_TOP_K, DEFAULT_THRESHOLD)
    choose_run(qtbot, setup, qc_run, monkeypatch)
    assert qc.path.text() == str(qc_run)
    assert qc.info.text() == "run (rf) scores 2 of the 3 gestures; not scored: Tickle"
    qc.top_k.setValue(1)
    assert qc.personalise.isEnabled() and qc.personalise.isChecked()  # DEFAULT_PERSONALISE
    qc.personalise.setChecked(False)
    # a file that is no model: one line, no model kept
    monkeypatch.setattr(QFileDialog, "getOpenFileName",
                        staticmethod(lambda *a, **k: (str(tmp_path / "gone.onnx"), "")))
    qtbot.mouseClick(qc.file_button, Qt.MouseButton.LeftButton)
    assert qc.path.text() == "" and "no such run folder or exported model" in qc.info.text()
    assert not qc.personalise.isEnabled() and not qc.choice().personalise
    choose_run(qtbot, setup, qc_run, monkeypatch)
    # the next setup of this study has it back, with its settings; another study does not
    again = CollectSetup(settings)
    qtbot.addWidget(again)
    again.set_protocol_file(str(proto))
    assert again.qc.path.text() == str(qc_run) and again.qc.top_k.value() == 1
    assert not again.qc.personalise.isChecked() and not again.qc.choice().personalise
    assert "not scored: Tickle" in again.qc.info.text()
    again.protocol.setCurrentIndex(0)  # a built-in protocol: another study
    assert again.qc.path.text() == ""
    # the next chooser opens where this one was left: beside the run (the other runs)
    assert start_folder(DIALOG_KIND) == str(qc_run.parent)


def test_a_session_with_a_qc_model_scores_the_gestures_it_knows(
        qtbot, env, qc_run, monkeypatch):  # noqa: F811 (env)
    proto, out = env
    console = make_console(qtbot)
    s = console.setup
    # P01, a person of the run: its fold that never saw them checks the trials; after
    # their first block it is fitted to them (off the screen's thread) and checks the rest
    fill_setup(qtbot, console, proto, out, "P01", blocks=2)
    choose_run(qtbot, s, qc_run, monkeypatch)
    s.qc.personalise.setChecked(True)
    path = two_blocks(qtbot, console, fitted_first=True)
    with SessionFile(path) as sess:
        trials, meta, events = sess.trials, sess.metadata, sess.events
    check = meta["trial_check"]
    assert check["model"] == "run/P01" and check["out_of_fold"] is True
    assert check["not_scored"] == ["Tickle"] and check["top_k"] == DEFAULT_TOP_K
    fitted = [e for e in events if e.get("kind") == "trial_check_personalised"]
    first = [t for t in trials if t.block == 0 and t.gesture != "Tickle" and t.usable]
    assert len(fitted) == 1 and fitted[0]["trials"] == len(first) == 2, fitted
    assert fitted[0]["model"] == "run/P01+2 own trials"
    for t in trials:
        if t.gesture == "Tickle":
            assert t.check is None
        else:  # block 0 by the run's fold, block 1 by it fitted to them
            model = "run/P01" if t.block == 0 else "run/P01+2 own trials"
            assert t.check["model"] == model and 1 <= t.check["rank"] <= 2, t


def test_the_consoles_check_adapts_to_the_participant_after_their_first_block(
        qtbot, env, qc_run3_adapted, monkeypatch):  # noqa: F811 (env)
    """On the console's worker: the first block is scored as trained, then the check
    reads the participant with the statistics of their trials so far (fails when the
    check does not adapt)."""
    proto, out = env
    console = make_console(qtbot)
    s = console.setup
    fill_setup(qtbot, console, proto, out, "P01", blocks=2)
    choose_run(qtbot, s, qc_run3_adapted, monkeypatch)
    s.qc.personalise.setChecked(False)  # the adaptation alone
    path = two_blocks(qtbot, console)
    with SessionFile(path) as sess:
        trials, meta, events = sess.trials, sess.metadata, sess.events
    assert meta["trial_check"]["model"] == "run/P01" and meta["trial_check"]["adapts"]
    first = [t for t in trials if t.block == 0 and t.usable]
    adapted = f"run/P01 (adapted to {len(first)} own trials)"
    assert [(e["trials"], e["model"]) for e in events
            if e.get("kind") == "trial_check_adapted"] == [(len(first), adapted)]
    assert {t.block: t.check["model"] for t in trials} == {0: "run/P01", 1: adapted}


def test_collect_qc_model_opens_the_console_with_it_in_the_setup(qtbot, env, qc_run):  # noqa: F811 (env)
    from tactile_studio.cli import build_parser
    from tactile_studio.cli.collect import console_options
    from tactile_studio.errors import UserError
    from tactile_studio.ui.collect.app import build_console

    proto, out = env
    base = ["collect", "--protocol", str(proto), "--participant", "P01", "--out", str(out)]
    args = build_parser().parse_args([*base, "--qc-model", str(qc_run), "--qc-top-k", "2"])
    console = build_console(console_options(args))
    qtbot.addWidget(console)
    qc = console.setup.qc
    assert qc.path.text() == str(qc_run) and qc.top_k.value() == 2
    assert qc.info.text() == "run (rf) scores 2 of the 3 gestures; not scored: Tickle"
    assert console.setup.choice().qc.model == str(qc_run)
    args = build_parser().parse_args([*base, "--qc-model", str(out / "no-run")])
    with pytest.raises(UserError, match="no such run folder or exported model"):
        console_options(args)
    args = build_parser().parse_args([*base, "--qc-model", str(qc_run), "--qc-personalise"])
    console = build_console(console_options(args))
    qtbot.addWidget(console)
    assert console.setup.qc.personalise.isChecked() and console.setup.choice().qc.personalise
    args = build_parser().parse_args([*base, "--qc-model", str(qc_run),
                                      "--no-qc-personalise"])
    console = build_console(console_options(args))
    qtbot.addWidget(console)
    assert not console.setup.choice().qc.personalise
    args = build_parser().parse_args([*base, "--qc-personalise"])
    with pytest.raises(UserError, match="--qc-personalise needs --qc-model"):
        console_options(args)


def test_a_pilot_with_mistakes_flags_them_redo_collects_again_and_keep_is_stored(
        qtbot, env, qc_run3, monkeypatch):  # noqa: F811 (env)
    """The console's pilot: a virtual participant performs another gesture than the
    prompted one in 80% of its trials (the simulator's "Wrong gestures"); the model of
    earlier (simulated) people flags them; the experimenter redoes the first and keeps
    the next flagged one."""
    proto, out = env
    console = make_console(qtbot)
    s = console.setup
    fill_setup(qtbot, console, proto, out, "P01", blocks=2)
    choose_run(qtbot, s, qc_run3, monkeypatch)
    assert s.qc.info.text() == "run (rf) scores all 3 gestures"
    s.qc.top_k.setValue(1)  # of three gestures, the top 3 is all of them
    s.pilot.setChecked(True)
    editor = s.device_form.fields["mistakes"].editor
    editor.clear()
    qtbot.keyClicks(editor, "0.8")
    qtbot.mouseClick(s.start_button, Qt.MouseButton.LeftButton)
    assert s.error.text() == "" and console.virtual is not None
    path = console.session.path
    runner = console.runner
    qtbot.mouseClick(console.buttons["primary"], Qt.MouseButton.LeftButton)  # Start
    decided: dict[str, int] = {}
    while True:  # the experimenter: Redo the first mistake flagged, Keep the others
        # held with its verdict in: the banner asks (held while the verdict is on its
        # way, it does not yet)
        qtbot.waitUntil(lambda: runner.held and console.redo_banner.isVisible()
                        or runner.state in State.DONE
                        or runner.state == State.BREAK and console.buttons["primary"].isEnabled(),
                        timeout=WAIT_MS)  # (the button, not the snapshot: a click on a
        # button the next tick enables is lost, and the loop asked again at once)
        if runner.state in State.DONE:
            break
        if runner.state == State.BREAK:
            qtbot.mouseClick(console.buttons["primary"], Qt.MouseButton.LeftButton)
            continue
        last = runner.records[-1]
        wrong = last.performed.split(";")[0] != last.gesture
        if wrong and "model_mismatch" in last.flags and "redo" not in decided:
            decided["redo"] = last.index
            qtbot.mouseClick(console.redo_banner.redo, Qt.MouseButton.LeftButton)
        else:
            decided.setdefault("keep", last.index)
            qtbot.mouseClick(console.redo_banner.keep, Qt.MouseButton.LeftButton)
    qtbot.waitUntil(lambda: console.session is None, timeout=WAIT_MS)
    with SessionFile(path) as sess:
        trials = sess.trials
    wrong = [t for t in trials if t.performed.split(";")[0] != t.gesture]
    seen = [(t.gesture, t.performed, t.flags, t.status) for t in trials]
    assert len(wrong) >= 3, seen
    caught = [t for t in wrong if "model_mismatch" in t.flags]
    # the small model of three simulated people catches most (4 of 5 here; the ≥90% of
    # the goal is measured with the real models: test_trial_check_model, bench_qc_real)
    assert len(caught) >= max(2, len(wrong) // 2), seen
    assert {"redo", "keep"} <= set(decided), decided
    redone = trials[decided["redo"]]
    assert redone.status == "redone" and redone.decision == "redo"
    again = [t for t in trials if t.index > redone.index and t.block == redone.block
             and t.gesture == redone.gesture]
    assert again and again[0].status == "ok"  # collected again in the same block
    kept = trials[decided["keep"]]
    assert kept.status == "ok" and kept.decision == "keep"
