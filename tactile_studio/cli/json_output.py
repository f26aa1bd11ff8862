"""``--json`` output: strict JSON on stdout, whatever a command has to say.

Python's ``json`` writes NaN and Infinity, which no other JSON parser reads: an old file's
``rate=nan`` made ``info --json`` unreadable to ``jq``. Every command prints its JSON
through :func:`print_json`, which writes them as null (a test keeps it so).
"""

from __future__ import annotations

import json
import sys
from typing import Any


def print_json(obj: Any, indent: int | None = 2) -> None:
    """``obj`` as strict JSON and a newline on stdout: NaN and ±inf become null, numpy
    values plain numbers, anything else JSON lacks its ``str``."""
    from tactile_studio.learn.experiments.runfolder import clean_json

    json.dump(clean_json(obj), sys.stdout, indent=indent, default=str, allow_nan=False)
    print()
