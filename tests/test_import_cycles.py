"""No import cycles anywhere in the house (core, ui, plugins), between modules or between
top-level packages, counting imports inside functions and under TYPE_CHECKING (grimp reads
every import statement); a circle planted in ui is found."""

from __future__ import annotations

from house_fixtures import house_imports


def test_no_module_or_package_cycles_in_the_whole_house(tmp_path):
    house = house_imports.build_house(tmp_path / "house")
    graphs = house_imports.graphs(house)
    # the graph saw the core, ui (and its two rooms) and the plugins
    for module in ("tactile_studio.storage.format.session_file", "tactile_studio.ui.main_window",
                   "tactile_studio.ui.collect.console", "tactile_studio.ui.research.window",
                   "tactile_studio.plugins.replay"):
        assert module in graphs["modules"], module
    assert {"storage", "learn", "ui", "plugins"} <= set(graphs["packages"])
    assert house_imports.cycles(house) == {"modules": [], "packages": []}


def test_a_circle_planted_in_ui_is_found(tmp_path):
    house = house_imports.build_house(tmp_path / "house")
    ui = house / "tactile_studio" / "ui"
    # two windows that import each other, one of them only inside a function
    (ui / "bad_a.py").write_text("import tactile_studio.ui.bad_b\n")
    (ui / "bad_b.py").write_text("def f():\n    from tactile_studio.ui import bad_a\n")
    # and a package circle: the sensor maths importing a widget
    (house / "tactile_studio" / "sensor" / "bad_up.py").write_text(
        "import tactile_studio.ui.grid_image\n")
    found = house_imports.cycles(house)
    assert ["tactile_studio.ui.bad_a", "tactile_studio.ui.bad_b"] in found["modules"]
    assert any("sensor" in c and "ui" in c for c in found["packages"])


def test_the_cycle_finder_finds_a_cycle():
    assert house_imports.cycles_of({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [
        ["a", "b", "c"]]
    assert house_imports.cycles_of({"a": {"b"}, "b": set()}) == []
