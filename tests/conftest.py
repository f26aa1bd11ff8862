"""Shared test setup: headless Qt, and no test touches the user's settings or cache."""

from __future__ import annotations

import os

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
os.environ.setdefault("TACTILE_STUDIO_TESTING", "1")
