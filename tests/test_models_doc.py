"""docs/models.md cannot rot: its `# file:` blocks are written out as a package; the model
is registered with register_model as the doc's script does and trains from the CLI; the
package's entry point (installed as a dist-info on the path) makes `tactile-studio train
--model frame_mlp` work in a fresh process, and the package's own test (check_model) passes.

Budget: ~30 s in-process (training 3 tiny folds, int8 export), ~40 s for the two subprocess
routes (slow).
"""

from __future__ import annotations

import json
import os
import re
import runpy
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
import torch
from learn_fixtures import make_dataset_folder

from tactile_studio.cli import main
from tactile_studio.learn.models import MODELS, unregister_model

DOC = Path(__file__).resolve().parents[1] / "docs" / "models.md"
BLOCK = re.compile(r"```(?:python|toml)\n# file: (\S+)\n(.*?)```", re.S)
GESTURES = ("Poke", "Heavy Pat", "Back & Forth Rub")


def doc_files() -> dict[str, str]:
    return {name: body for name, body in BLOCK.findall(DOC.read_text(encoding="utf-8"))}


def write_package(root: Path) -> dict[str, str]:
    files = doc_files()
    for name, body in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(body, encoding="utf-8")
    return files


def install_entry_points(root: Path) -> Path:
    """What ``pip install`` leaves for importlib.metadata: a dist-info with the pyproject's
    entry points, in a folder put on the path (with the sources)."""
    meta = tomllib.loads((root / "pyproject.toml").read_text())["project"]
    site = root / "site"
    info = site / f"{meta['name'].replace('-', '_')}-{meta['version']}.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {meta['name']}\n"
                                   f"Version: {meta['version']}\n")
    lines = []
    for group, eps in meta["entry-points"].items():
        lines.append(f"[{group}]")
        lines += [f"{name} = {target}" for name, target in eps.items()]
    (info / "entry_points.txt").write_text("\n".join(lines) + "\n")
    return site


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("models-doc")
    make_dataset_folder(root / "data", participants=3, blocks=2, gestures=GESTURES)
    return root


def _train_args(data: Path, out: Path) -> list[str]:
    return ["--data", str(data / "data"), "--preset", "tiny", "--eval", "lopo",
            "--out", str(out), "--cache-dir", str(data / "cache"), "--threads", "1"]


def _check_metrics(out: Path) -> dict:
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["model"] == "frame_mlp" and len(metrics["per_fold"]) == 3
    for key in ("accuracy", "trial_accuracy"):
        assert 0.0 <= metrics[key] <= 1.0, key
    # 3 gestures: chance is 1/3; the easy simulated participants are well above it
    assert metrics["trial_accuracy"] > 0.5
    return metrics


def test_the_doc_holds_a_whole_package():
    assert set(doc_files()) == {"pyproject.toml", "src/frame_mlp.py", "train_frame_mlp.py",
                                "tests/test_frame_mlp.py"}


@pytest.mark.slow
def test_a_model_added_from_the_doc_trains_from_the_cli(data, tmp_path, monkeypatch, capsys):
    torch.set_num_threads(1)
    write_package(tmp_path)
    monkeypatch.syspath_prepend(str(tmp_path / "src"))
    monkeypatch.delitem(sys.modules, "frame_mlp", raising=False)
    out = tmp_path / "run"
    monkeypatch.setattr(sys, "argv", ["train_frame_mlp.py", *_train_args(data, out)])
    try:
        with pytest.raises(SystemExit) as done:
            runpy.run_path(str(tmp_path / "train_frame_mlp.py"), run_name="__main__")
        assert done.value.code == 0, capsys.readouterr().err
        assert MODELS["frame_mlp"].streaming.cached
        metrics = _check_metrics(out)
        assert f"{metrics['accuracy']:.3f}" in capsys.readouterr().out
        config = json.loads((out / "config.json").read_text())
        assert config["config"]["model"] == "frame_mlp"
        # the declared int8 export works, as the doc's last command says
        assert main(["export-model", str(out), "--format", "int8", "--threads", "1"]) == 0
        assert "qoperator quantisation" in capsys.readouterr().out
        report = json.loads((out / "export" / "int8.json").read_text())
        assert len(report["folds"]) == 3
    finally:
        unregister_model("frame_mlp")
    assert "frame_mlp" not in MODELS


@pytest.mark.slow
def test_the_entry_point_route_and_the_packages_own_test(data, tmp_path):
    write_package(tmp_path)
    site = install_entry_points(tmp_path)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(site), str(tmp_path / "src"), *filter(None, [os.environ.get("PYTHONPATH")])])}
    out = tmp_path / "run"
    proc = subprocess.run(
        [sys.executable, "-m", "tactile_studio", "train", "--model", "frame_mlp",
         *_train_args(data, out)],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=240)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    _check_metrics(out)
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "--rootdir",
         str(tmp_path), str(tmp_path / "tests")],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=240)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "1 passed" in proc.stdout
    # a broken entry point is reported by name and does not hide the others
    info = next(site.glob("*.dist-info"))
    with (info / "entry_points.txt").open("a") as f:
        f.write("broken_model = no_such_module:MODEL\n")
    proc = subprocess.run(
        [sys.executable, "-m", "tactile_studio", "train", "--model", "broken_model",
         *_train_args(data, tmp_path / "broken")],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=240)
    assert proc.returncode == 1
    assert proc.stderr.strip().splitlines()[-1].startswith(
        "tactile-studio: error: model 'broken_model' failed to load: ModuleNotFoundError")
