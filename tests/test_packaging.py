"""Packaging: every package folder is installed under the tactile_studio namespace."""

from __future__ import annotations

import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MAPPED = {"tactile_studio": "tactile_studio", "ui": "tactile_studio.ui",
          "plugins": "tactile_studio.plugins", "resources": "tactile_studio.resources"}


def test_every_package_folder_is_listed_in_pyproject():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(config["packages"])
    found = set()
    for folder, namespace in MAPPED.items():
        for init in (ROOT / folder).rglob("__init__.py"):
            rel = init.parent.relative_to(ROOT / folder).parts
            found.add(".".join((namespace, *rel)))
    assert found - listed == set(), "add these to [tool.setuptools] packages"


def test_mapped_packages_import_under_the_namespace():
    import tactile_studio.plugins.replay
    import tactile_studio.resources

    assert Path(tactile_studio.plugins.replay.__file__).parent.name == "plugins"
    assert (Path(tactile_studio.resources.__file__).parent / "__init__.py").exists()
