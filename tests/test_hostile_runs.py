"""A run folder from someone else (issue 43, the hunt): config.json and fold.json of other
shapes ended evaluate, export-model and compare in tracebacks (a list where options go,
text where a window length goes, no data_info, repeated labels, predictions as text) or
in allocating what the file claimed (10^12 classes: 7 TiB); a fold's model fingerprint
named ``../../../etc/hostname`` and had that file read and hashed. Now each command ends
in one line naming the file and the field, exit 1. A real tiny rf run, edited per case."""

from __future__ import annotations

import hashlib
import json
import shutil
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from learn_fixtures import make_dataset_folder

from tactile_studio.cli import main
from tactile_studio.errors import EXIT_ERROR

GESTURES3 = ("Poke", "Heavy Pat", "Back & Forth Rub")


@pytest.fixture(scope="module")
def run(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("hostile-runs")
    make_dataset_folder(root / "data", participants=3, blocks=2, gestures=GESTURES3)
    argv = ["train", "--data", root / "data", "--model", "rf", "--preset", "tiny", "--eval",
            "lopo", "--out", root / "run", "--cache-dir", root / "cache", "--set",
            "n_estimators=10"]
    assert main([str(a) for a in argv]) == 0
    return root / "run"


def _config(edit: Callable[[dict[str, Any]], None]) -> Callable[[Path], None]:
    def apply(run: Path) -> None:
        cfg = json.loads((run / "config.json").read_text())
        edit(cfg)
        (run / "config.json").write_text(json.dumps(cfg))
    return apply


def _fold(edit: Callable[[dict[str, Any]], None]) -> Callable[[Path], None]:
    def apply(run: Path) -> None:
        path = run / "folds" / "r0-P01" / "fold.json"
        rec = json.loads(path.read_text())
        edit(rec)
        path.write_text(json.dumps(rec))
    return apply


def _data_info(key: str, value: Any) -> Callable[[dict[str, Any]], None]:
    return lambda c: c["resolved"]["data_info"].__setitem__(key, value)


CASES = {
    "overrides-a-list": (_config(lambda c: c["config"].__setitem__("overrides", [1, 2])),
                         "config.json: config.overrides is [1, 2], not dict[str, Any]"),
    "window-as-text": (_config(lambda c: c["config"].__setitem__("window_s", "nan")),
                       "config.json: config.window_s is 'nan', not float | None"),
    "no-data-info": (_config(lambda c: c["resolved"].pop("data_info")),
                     "config.json: resolved.data_info is missing"),
    "10^12-classes": (_config(_data_info("n_classes", 10**12)),
                      "config.json: resolved.data_info.n_classes is 1000000000000, not "
                      "2..1000 classes"),
    "repeated-labels": (_config(lambda c: c["resolved"]["dataset"].__setitem__(
        "labels", ["Poke", "Poke", "Heavy Pat"])),
        "config.json: resolved.dataset.labels is ['Poke', 'Poke', 'Heavy Pat'], not 3 "
        "different gesture names"),
    "predictions-as-text": (_fold(lambda r: r.__setitem__("predictions", "x")),
                            "fold.json: predictions are not lists of labels"),
    "predictions-of-2-classes": (_fold(lambda r: r.__setitem__(
        "predictions", {"y_true": [0], "owner": [0], "probs": [[0.5, 0.5]]})),
        "fold.json: predictions do not fit the run's 3 labels"),
    "fingerprint-of-a-file-elsewhere": (_fold(lambda r: r.__setitem__(
        "model_sha256", {"../../../../etc/hostname": hashlib.sha256(b"").hexdigest()})),
        "fold.json: model_sha256 is {'../../../../etc/hostname'"),
}


@pytest.mark.parametrize("case", CASES, ids=CASES)
def test_a_strangers_run_folder_ends_every_reader_in_one_line(run: Path, tmp_path: Path,
                                                             capsys, case: str) -> None:
    edit, said = CASES[case]
    other = tmp_path / "run"
    shutil.copytree(run, other)
    edit(other)
    cache = ["--cache-dir", str(run.parent / "cache")]
    for argv in (["evaluate", str(other), *cache],
                 ["export-model", str(other), "--format", "onnx", *cache],
                 ["compare", str(other), str(run)]):
        code = main(argv)
        err = capsys.readouterr().err
        lines = [ln for ln in err.splitlines() if ln.strip()]
        assert code == EXIT_ERROR and "Traceback" not in err, (argv, err)
        assert lines[-1].startswith(f"tactile-studio: error: {other}"), (argv, err)
        assert said in lines[-1], (argv, lines[-1])
