"""tools/house_imports.py for the tests: the product code as Python imports it (ui/,
plugins/ and resources/ placed inside tactile_studio/), for the import guards."""

from __future__ import annotations

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("house_imports", ROOT / "tools" / "house_imports.py")
house_imports = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(house_imports)
