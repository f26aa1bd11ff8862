"""Soft limits every stage shares: the indenter never goes below ``floor_z`` nor leaves
the x/y box; checked in sensor coordinates before anything is sent or moved."""

from __future__ import annotations

from typing import Any

from tactile_studio.instruments.contract import SoftLimitError
from tactile_studio.plugin_settings import Setting

LIMIT_SETTINGS: tuple[Setting, ...] = (
    Setting("safe_z", "float", 5.0, "retract height above the skin, mm", minimum=0.5),
    Setting("floor_z", "float", -1.5, "soft limit: the indenter never goes below this z, mm"),
    Setting("x_min", "float", -20.0, "soft limit, mm"),
    Setting("x_max", "float", 100.0, "soft limit, mm"),
    Setting("y_min", "float", -20.0, "soft limit, mm"),
    Setting("y_max", "float", 100.0, "soft limit, mm"),
)


def check_limits(name: str, settings: dict[str, Any], x: float, y: float, z: float) -> None:
    """SoftLimitError (one line) if (x, y, z) is outside the stage's soft limits."""
    s = settings
    if z < s["floor_z"]:
        raise SoftLimitError(f"stage {name}: z={z:.3f} mm is below the floor "
                             f"floor_z={s['floor_z']} mm (refused, nothing moved)")
    for axis, v in (("x", x), ("y", y)):
        if not s[f"{axis}_min"] <= v <= s[f"{axis}_max"]:
            raise SoftLimitError(f"stage {name}: {axis}={v:.3f} mm is outside "
                                 f"{s[f'{axis}_min']}..{s[f'{axis}_max']} mm (refused)")
