"""Shared test setup: headless Qt, and no test touches the user's settings or cache."""

from __future__ import annotations

import os
import tempfile

import pytest

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
os.environ.setdefault("TACTILE_STUDIO_TESTING", "1")
# the app's data, cache and config folders (tactile_studio.paths) live in one temporary
# folder per test run; tests that need their own set them with monkeypatch
_APPDIRS = tempfile.mkdtemp(prefix="tactile-studio-appdirs-")
for _name in ("DATA", "CACHE", "CONFIG"):
    os.environ.setdefault(f"TACTILE_STUDIO_{_name}_DIR", os.path.join(_APPDIRS, _name.lower()))
# Lab Streaming Layer: loopback only, a session ID of its own (read when liblsl loads)
os.environ.setdefault("LSLAPICFG", os.path.join(os.path.dirname(__file__), "lsl_api.cfg"))



@pytest.fixture
def wait_until():
    """The shared bounded wait (tests/waiting.py), for tests that prefer a fixture."""
    from waiting import wait_until as wait
    return wait
