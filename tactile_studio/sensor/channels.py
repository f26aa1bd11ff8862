"""A frame's channels by name: labels, roles and grid positions in stream order, and
the layout a bare channel count implies.

Shared by the LSL outlet (streams/lsl_meta.py), the lsl device and XDF files (storage/
xdf_export.py, storage/exchange/importers/xdf.py), so every tool names a channel the same way.
"""

from __future__ import annotations

import math
from typing import Any

from tactile_studio.sensor.layout import SHEARSENSE_6X6, Layout, get_layout

RAW, DECODED = "raw", "decoded"
ROLE_NAMES = ("y_neg", "x_neg", "centre", "x_pos", "y_pos")  # layout.py's channel roles
DECODED_ROLES = ("normal", "shear_x", "shear_y")


def frame_channels(layout: Layout, content: str) -> list[dict[str, Any]]:
    """One dict per stream channel (label, type, unit, taxel, row, col), in stream order:
    raw channels in the device's order; decoded all normal (row-major), then shear-x,
    then shear-y."""
    out: list[dict[str, Any]] = []
    if content == RAW:
        k = layout.channels_per_taxel
        for ch in range(layout.n_channels):
            taxel, role = divmod(ch, k)
            r, c = layout.taxel_rc(taxel)
            name = layout.taxel_name(r, c)
            role_name = ROLE_NAMES[role] if k == 5 else "pressure"
            out.append({"label": f"{name}:{role_name}" if k > 1 else name, "type": role_name,
                        "unit": "counts", "taxel": name, "row": r, "col": c})
        return out
    roles = DECODED_ROLES if layout.has_shear else DECODED_ROLES[:1]
    for role in roles:  # all normal channels first (row-major), then shear-x, shear-y
        for r in range(layout.rows):
            for c in range(layout.cols):
                name = layout.taxel_name(r, c)
                out.append({"label": f"{name}:{role}", "type": role, "unit": layout.units,
                            "taxel": name, "row": r, "col": c})
    return out


def layout_for_channels(n: int) -> Layout | None:
    """The layout a bare channel count implies (180 -> shearsense-6x6, N*N -> grid-NxN),
    or None."""
    if n == SHEARSENSE_6X6.n_channels:
        return SHEARSENSE_6X6
    side = math.isqrt(n)
    return get_layout(f"grid-{side}x{side}") if n > 0 and side * side == n else None
