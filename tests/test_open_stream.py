"""One way to open a stream: ``acquisition/open_stream.py`` is the only constructor of
the acquisition engine in the product, and what it hands out is held by the protocols
(``LiveStream``, ``FrameStream``), which the engine meets."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

import tactile_studio
from tactile_studio.acquisition.open_stream import open_stream
from tactile_studio.devices.frame_stream import FrameStream, LiveStream, RecordableStream
from tactile_studio.errors import SettingsError

REPO = Path(tactile_studio.__file__).parent.parent
ROOMS = ("tactile_studio", "ui", "plugins", "benchmarks", "tools")  # tests make their own
SEAM = "tactile_studio/acquisition/open_stream.py"


def _engine_makers() -> list[str]:
    """Every product, benchmark or tool file calling ``AcquisitionEngine(...)``."""
    makers = []
    for room in ROOMS:
        for path in sorted((REPO / room).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text(), str(path))):
                if not isinstance(node, ast.Call):
                    continue
                f = node.func
                name = f.id if isinstance(f, ast.Name) else getattr(f, "attr", None)
                if name == "AcquisitionEngine":
                    makers.append(f"{path.relative_to(REPO)}:{node.lineno}")
    return makers


def test_only_open_stream_makes_an_engine() -> None:
    makers = _engine_makers()
    assert [m.split(":")[0] for m in makers] == [SEAM], makers


def _engine_importers(repo: Path = REPO) -> list[str]:
    """Product files outside acquisition/ and devices/ that import the engine's class
    by name from anywhere (``from tactile_studio.devices import AcquisitionEngine``
    passes the import contract, which watches the module ``devices.engine``)."""
    found = []
    for room in ("tactile_studio", "ui", "plugins"):
        for path in sorted((repo / room).rglob("*.py")):
            rel = path.relative_to(repo).as_posix()
            if rel.startswith(("tactile_studio/acquisition/", "tactile_studio/devices/")):
                continue
            for node in ast.walk(ast.parse(path.read_text(), rel)):
                if isinstance(node, ast.ImportFrom) and any(
                        a.name == "AcquisitionEngine" for a in node.names):
                    found.append(f"{rel}:{node.lineno}")
    return found


def test_nothing_above_acquisition_names_the_engine_class() -> None:
    assert _engine_importers() == []


def test_the_engine_is_not_re_exported_above_devices() -> None:
    """Holders get the engine from open_stream, never by importing its class: the
    packages above devices do not hand the class out."""
    import tactile_studio.acquisition as acquisition
    import tactile_studio.live as live

    for package in (acquisition, live):
        assert not hasattr(package, "AcquisitionEngine"), package.__name__


def test_open_stream_by_name_or_device_meets_the_protocols() -> None:
    from tactile_studio.devices.registry import create_device

    by_name = open_stream("simulated", {"seed": 3, "speed": 0}, capacity=1024)
    made = open_stream(create_device("simulated", {"seed": 3}))
    for stream in (by_name, made):
        assert isinstance(stream, LiveStream)
        assert isinstance(stream, RecordableStream) and isinstance(stream, FrameStream)
        assert stream.state == "idle" and stream.frames == 0
    assert by_name.capacity == 1024
    assert by_name.device_info()["settings"]["seed"] == 3
    with pytest.raises(SettingsError):
        open_stream("simulated", {"rate": "fast"})
