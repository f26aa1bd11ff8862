"""The whole house's import contracts (pyproject.toml [tool.importlinter]) hold on the
product code as Python imports it (ui/ and plugins/ placed inside tactile_studio/, by
tools/house_imports.py), and they would catch a break: the same contracts fail on a copy
with a forbidden import planted."""

from __future__ import annotations

import tomllib

import pytest
from house_fixtures import ROOT, house_imports


@pytest.fixture(scope="module")
def contracts() -> dict[str, dict]:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]
    return {c["name"]: c for c in config["contracts"]}


def test_the_layers_hold_over_the_whole_house(tmp_path, contracts):
    house = house_imports.build_house(tmp_path / "house")
    assert (house / "tactile_studio" / "ui" / "main_window.py").exists()
    assert (house / "tactile_studio" / "plugins" / "replay.py").exists()
    result = house_imports.lint(house)
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-2000:]
    assert f"Contracts: {len(contracts)} kept, 0 broken." in result.stdout
    # the GUI launchers are the only imports let through, and each one is used
    assert "only ui imports Qt KEPT (5 ignored imports)" in result.stdout


def test_only_ui_is_left_out_of_the_qt_ban(contracts):
    """A new top-level package or module is banned from Qt (and from naming a plugin)
    as soon as it exists: the contracts list every one but ui (and plugins, for itself)."""
    tops = {p.stem for p in (ROOT / "tactile_studio").iterdir()
            if (p.suffix == ".py" and p.stem != "__init__") or (p / "__init__.py").exists()}
    tops |= set(house_imports.PLACED)
    qt = {m.removeprefix("tactile_studio.") for m in contracts["only ui imports Qt"]
          ["source_modules"]}
    assert qt == tops - {"ui"}
    plugins = {m.removeprefix("tactile_studio.") for m in
               contracts["plugins are reached only through entry points"]["source_modules"]}
    assert plugins == tops - {"plugins"}
    engine = {m.removeprefix("tactile_studio.") for m in
              contracts["only acquisition opens a stream"]["source_modules"]}
    assert engine == tops - {"acquisition", "devices"}
    # the declared exceptions are the CLI's GUI launchers, nothing else
    for line in contracts["only ui imports Qt"]["ignore_imports"]:
        importer, imported = line.split(" -> ")
        assert importer.startswith("tactile_studio.cli.")
        assert imported.startswith("tactile_studio.ui.")


PLANTED = {
    # ui reaching up into the CLI
    ("ui", "bad_upward.py"): "import tactile_studio.cli.gui\n",
    # the sensor maths reaching up into storage
    ("sensor", "bad_upward.py"): "import tactile_studio.storage.format.session_file\n",
    # the core, and a plugin, importing Qt
    ("learn", "bad_qt.py"): "import PySide6.QtCore\n",
    ("plugins", "bad_qt.py"): "import pyqtgraph\n",
    # the collection screens reaching into the research workspace
    ("ui", "collect", "bad_research.py"): "import tactile_studio.ui.research.player\n",
    # a widget, and a core room, building their own engine instead of opening a stream
    ("ui", "bad_engine.py"): "from tactile_studio.devices.engine import AcquisitionEngine\n",
    ("health", "bad_engine.py"): "import tactile_studio.devices.engine\n",
    # the core naming a plugin instead of finding it through its entry point
    ("live", "bad_plugin.py"): "import tactile_studio.plugins.simulated\n",
    # learn's data reaching up into the runs that use it
    ("learn", "data", "bad_upward.py"): "import tactile_studio.learn.experiments.sweep\n",
    # the sensor books reaching up into the exchange formats
    ("storage", "books", "bad_up.py"): "import tactile_studio.storage.exchange.xdf_scan\n",
}


def test_a_planted_import_breaks_the_contracts(tmp_path, contracts):
    house = house_imports.build_house(tmp_path / "house")
    for parts, text in PLANTED.items():
        (house / "tactile_studio").joinpath(*parts).write_text(text)
    result = house_imports.lint(house)
    assert result.returncode != 0
    out = " ".join(result.stdout.split())  # a long chain is wrapped
    assert f"Contracts: 0 kept, {len(contracts)} broken." in out, out[-3000:]
    for line in ("tactile_studio.ui.bad_upward -> tactile_studio.cli.gui",
                 "tactile_studio.sensor.bad_upward -> tactile_studio.storage.format.session_file",
                 "tactile_studio.learn.bad_qt -> PySide6",
                 "tactile_studio.plugins.bad_qt -> pyqtgraph",
                 "tactile_studio.ui.collect.bad_research -> tactile_studio.ui.research.player",
                 "tactile_studio.ui.bad_engine -> tactile_studio.devices.engine",
                 "tactile_studio.health.bad_engine -> tactile_studio.devices.engine",
                 "tactile_studio.live.bad_plugin -> tactile_studio.plugins.simulated",
                 "tactile_studio.learn.data.bad_upward -> tactile_studio.learn.experiments.sweep",
                 "tactile_studio.storage.books.bad_up -> tactile_studio.storage.exchange.xdf_scan"):
        assert line in out, line
