"""Where files live: the platform's folders (platformdirs), overridable by environment."""

from __future__ import annotations

import re
from pathlib import Path

import platformdirs
from learn_fixtures import make_dataset_folder

from tactile_studio import paths
from tactile_studio.cli import main
from tactile_studio.learn.data.cache import default_cache_dir
from tactile_studio.learn.data.dataset import build_dataset

CORE = Path(__file__).resolve().parents[1] / "tactile_studio"


def test_dataset_cache_follows_the_environment_then_the_platform(monkeypatch, tmp_path):
    monkeypatch.setenv("TACTILE_STUDIO_CACHE_DIR", str(tmp_path / "mine"))
    assert default_cache_dir() == tmp_path / "mine" == paths.cache_dir()
    monkeypatch.delenv("TACTILE_STUDIO_CACHE_DIR")
    expected = Path(platformdirs.user_cache_dir(paths.APP_NAME, paths.APP_AUTHOR))
    assert default_cache_dir() == expected


def test_a_dataset_built_without_cache_dir_is_cached_in_the_app_cache(monkeypatch, tmp_path):
    monkeypatch.setenv("TACTILE_STUDIO_CACHE_DIR", str(tmp_path / "cache"))
    make_dataset_folder(tmp_path / "data", participants=2, blocks=1)
    build_dataset([str(tmp_path / "data")], "physical")
    assert len(list((tmp_path / "cache" / "datasets").glob("*.npz"))) == 1


def test_no_hard_coded_home_folders_in_the_core():
    pattern = re.compile(r"Path\.home\(\)|[\"']~/|\.cache[\"'/]|XDG_CACHE_HOME")
    offenders = [f"{p.relative_to(CORE)}:{i}" for p in CORE.rglob("*.py")
                 for i, line in enumerate(p.read_text().splitlines(), 1)
                 if pattern.search(line) and p.name != "paths.py"]
    assert offenders == []


def test_cache_dir_help_names_the_override(capsys):
    try:
        main(["train", "--help"])
    except SystemExit:
        pass
    assert "TACTILE_STUDIO_CACHE_DIR" in capsys.readouterr().out
