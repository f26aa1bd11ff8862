"""Screenshots of the console's trial check (issue 46) from a real session and a real model.

``QT_QPA_PLATFORM=offscreen .venv/bin/python tools/screenshots/make_qc_screenshots.py
[OUT_DIR]`` (default docs/screenshots) trains a small rf run (leave-one-participant-out
over three simulated people, shear9 without Tickle, so the setup has a gesture it cannot
score), then writes:

* collect-setup-qc.png: the setup with that run as its QC model;
* collect-console-model-flag.png: the participant performed Wide Pinch when Twist was
  prompted; the model's reason in the log and the amber banner with Redo and Keep;
* collect-console-block-summary.png: block 1 over (a break), its summary under the log.

Works headless; takes about a minute.
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(Path(__file__).resolve().parent))
from make_collect_screenshots import _pump, _settle  # noqa: E402 (beside this script)

CONSOLE_SIZE = (1500, 900)
MISTAKES = {"Twist": "Wide Pinch", "Poke": "Heavy Pat"}  # prompted -> what was performed


def _train(tmp: Path) -> Path:
    sys.path.insert(0, str(ROOT / "tests"))  # the simulated-session writer the tests use
    from learn_fixtures import make_dataset_folder

    from tactile_studio.learn.experiments.experiment import ExperimentConfig, run_experiment
    from tactile_studio.simulate import GESTURE_NAMES

    gestures = tuple(g for g in GESTURE_NAMES if g != "Tickle")
    make_dataset_folder(tmp / "earlier", participants=3, blocks=3, gestures=gestures)
    cfg = ExperimentConfig(data=[str(tmp / "earlier")], model="rf", evaluation="lopo",
                           threads=1, cache_dir=str(tmp / "cache"))
    run_experiment(cfg, tmp / "runs" / "rf-earlier")
    return tmp / "runs" / "rf-earlier"


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    out = Path(argv[0]) if argv else ROOT / "docs" / "screenshots"
    out.mkdir(parents=True, exist_ok=True)
    os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
    tmp = Path(tempfile.mkdtemp(prefix="qc-shots-"))
    os.environ["TACTILE_STUDIO_SETTINGS"] = str(tmp / "settings.ini")
    run = _train(tmp)

    from PySide6.QtWidgets import QApplication

    from tactile_studio.protocol.snapshot import State
    from tactile_studio.ui.collect.console import CollectConsole

    app = QApplication.instance() or QApplication([])
    console = CollectConsole()
    console.resize(*CONSOLE_SIZE)
    console.show()
    s = console.setup
    s.participant.setText("P01")  # a person of the run: checked by the fold without them
    s.out_dir.setText(str(tmp / "data"))
    s.set_device("simulated", {"speed": "4", "gesture": "idle", "seed": "3"})
    s.blocks.setValue(2)
    s.qc.set_model(str(run))
    _settle(app, 0.2)
    console.grab().save(str(out / "collect-setup-qc.png"))

    choice = s.choice()
    choice.protocol = choice.protocol.with_overrides(break_every=1, break_min_s=120.0,
                                                     free_play_s=0.0)
    assert console.start_session(choice), s.error.text()
    runner, dev = console.runner, console.engine.device

    def snap():  # noqa: ANN202
        return runner.snapshot()

    def trial(name: str, key: str) -> None:
        n = len(snap().trials)
        dev.perform(MISTAKES.get(name, name), duration_s=2.4)
        console.forward_key(key)
        _pump(app, lambda: len(snap().trials) > n and snap().state not in
              (State.RECORDING, State.TRIAL_END))
        _pump(app, lambda: runner.take_verdict() or True)  # (a tick takes it)
        _settle(app, 0.3)

    console.primary_action()  # Start
    _pump(app, lambda: snap().state == State.WAITING)
    shot_taken = False
    while snap().state not in (State.BREAK, State.FINISHED):
        g = next(x for x in snap().gestures if x.name == snap().prompted)
        trial(g.name, g.key)
        if console.redo_banner.isVisible() and not shot_taken and g.name in MISTAKES:
            dev.perform("Constant Touch", duration_s=8.0)  # the next touch on the map
            _settle(app, 0.8)
            console.grab().save(str(out / "collect-console-model-flag.png"))
            shot_taken = True
        if console.redo_banner.isVisible():
            console.keep_flagged()
        _settle(app, 0.2)
    _settle(app, 0.5)
    console.grab().save(str(out / "collect-console-block-summary.png"))
    console.close()
    for name in ("collect-setup-qc", "collect-console-model-flag",
                 "collect-console-block-summary"):
        print(out / f"{name}.png")
    return 0 if shot_taken else 1


if __name__ == "__main__":
    raise SystemExit(main())
