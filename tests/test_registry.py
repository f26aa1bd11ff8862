"""One registry mechanism for devices, instruments and models (tactile_studio/registry.py):
names from a real entry-point group (a dist-info put on the path, as pip leaves it) plus
in-process registration; an entry's module is imported once, when first asked for; a
broken entry is reported by name and hides nothing else."""

from __future__ import annotations

import sys

import pytest

from tactile_studio.devices import (
    DevicePlugin,
    available_plugins,
    create_device,
    plugin_class,
    register_device,
    unregister_device,
)
from tactile_studio.errors import UserError
from tactile_studio.instruments import StagePlugin, available, create_stage, register_stage
from tactile_studio.instruments.registry import STAGE_GROUP, STAGES
from tactile_studio.plugins.sim_stage import SimulatedStage
from tactile_studio.plugins.simulated import SimulatedSensor
from tactile_studio.registry import Registry, subclass_of

GROUP = "tactile_studio_test.shapes"


class Shape:
    pass


@pytest.fixture
def site(tmp_path, monkeypatch):
    """A package with three entry points, one of them broken, installed on the path."""
    (tmp_path / "shapes_pkg.py").write_text(
        "import sys\n"
        "sys.modules.setdefault('shapes_pkg_imports', []).append(1)\n"
        "from test_registry import Shape\n"
        "class Square(Shape):\n    pass\n"
        "class Circle(Shape):\n    pass\n"
        "NOT_A_SHAPE = 3\n")
    info = tmp_path / "shapes_pkg-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: shapes-pkg\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text(
        f"[{GROUP}]\nsquare = shapes_pkg:Square\nbroken = no_such_module:Thing\n"
        "circle = shapes_pkg:Circle\nnumber = shapes_pkg:NOT_A_SHAPE\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "shapes_pkg", raising=False)
    monkeypatch.delitem(sys.modules, "shapes_pkg_imports", raising=False)
    return tmp_path


def test_entry_points_are_listed_without_importing_and_loaded_once(site):
    shapes = Registry(GROUP, "shape", subclass_of(Shape))
    assert shapes.names() == ["square", "broken", "circle", "number"]  # declaration order
    assert "shapes_pkg" not in sys.modules  # listing imports nothing
    square = shapes.get("square")
    assert square.__name__ == "Square" and issubclass(square, Shape)
    assert shapes.get("square") is square and shapes.get("circle").__name__ == "Circle"
    assert sys.modules["shapes_pkg_imports"] == [1]  # imported once, kept


def test_a_broken_entry_is_reported_by_name_and_hides_nothing(site):
    shapes = Registry(GROUP, "shape", subclass_of(Shape))
    found = shapes.all()
    assert isinstance(found["broken"], ModuleNotFoundError)
    assert str(found["number"]) == "shapes_pkg:NOT_A_SHAPE is not a Shape subclass"
    assert found["square"].__name__ == "Square" and found["circle"].__name__ == "Circle"
    with pytest.raises(UserError, match=r"^shape plugin 'broken' failed to load: No module"):
        shapes.get("broken")
    with pytest.raises(UserError, match=r"^unknown shape 'hexagon' \(available: square, "):
        shapes.get("hexagon")
    assert shapes.all()["broken"] is found["broken"]  # the failure is kept, not retried


def test_in_process_registration_beside_the_entry_points(site):
    shapes = Registry(GROUP, "shape", subclass_of(Shape))

    class Triangle(Shape):
        pass

    assert shapes.register("triangle", Triangle) is Triangle
    assert shapes.names()[-1] == "triangle" and shapes.get("triangle") is Triangle
    with pytest.raises(ValueError, match="a shape named 'square' is already registered"):
        shapes.register("square", Triangle)
    with pytest.raises(TypeError, match="is not a Shape subclass"):
        shapes.register("text", str)
    shapes.register("square", Triangle, replace=True)  # a notebook cell run again
    assert shapes.get("square") is Triangle
    shapes.unregister("square")
    shapes.unregister("triangle")
    assert shapes.get("square").__name__ == "Square" and "triangle" not in shapes.names()


def test_devices_and_stages_use_it():
    # the built-ins come from this project's own entry points, sorted by name as before
    devices = available_plugins()
    assert list(devices) == sorted(devices) and devices["simulated"] is SimulatedSensor
    assert available(STAGE_GROUP)["simulated"] is SimulatedStage

    class MatDevice(SimulatedSensor):
        name = "notebook-mat"

    class BenchStage(SimulatedStage):
        name = "notebook-bench"

    try:
        assert register_device(MatDevice) is MatDevice
        assert plugin_class("notebook-mat") is MatDevice
        assert "notebook-mat" in available_plugins()
        assert isinstance(create_device("notebook-mat", {"rate": 50}), DevicePlugin)
        with pytest.raises(ValueError, match="already registered"):
            register_device(type("Other", (SimulatedSensor,), {"name": "simulated"}))
        register_stage(BenchStage)
        assert isinstance(create_stage("notebook-bench"), StagePlugin)
    finally:
        unregister_device("notebook-mat")
        STAGES.unregister("notebook-bench")
    assert "notebook-mat" not in available_plugins()
    with pytest.raises(UserError, match=r"^unknown device 'notebook-mat' \(available: "):
        plugin_class("notebook-mat")
    with pytest.raises(UserError, match=r"^unknown stage 'notebook-bench' \(available: "):
        create_stage("notebook-bench")
