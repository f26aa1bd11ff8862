"""Sensor layouts as data: how raw channels map to taxels, and how to read them.

A layout says where each taxel sits, which raw channel plays which role, how raw values
move under load, and the calibration from relative change to kPa. Everything that
decodes, draws or simulates a sensor asks the layout instead of hard-coding 6x6x5.

Coordinates: ``x`` grows with the column index (to the right on screen), ``y`` grows with
the row index (down on screen, row 0 at the top, as in an image). Shear arrows use the
same axes, so an arrow points the way the skin is dragged.
"""

from __future__ import annotations

import functools
import string
from dataclasses import dataclass

import numpy as np

from tactile_studio.errors import UserError

# Roles of the five channels of a ShearSense taxel (DESIGN.md: index 2 is the centre,
# 0 and 4 the y pair, 1 and 3 the x pair). The plus shape is read top, left, centre,
# right, bottom: 0 faces -y, 1 faces -x, 3 faces +x, 4 faces +y.
Y_NEG, X_NEG, CENTRE, X_POS, Y_POS = 0, 1, 2, 3, 4


@dataclass(frozen=True)
class Calibration:
    """Relative change to kPa.

    Normal: two linear ranges split at ``normal_split_kpa`` (paper: 0.01 /kPa below
    9.3 kPa, 6.2e-3 /kPa above). Shear: one linear slope (paper: ~0.11 /kPa).
    """

    normal_slope_low: float = 0.01
    normal_slope_high: float = 6.2e-3
    normal_split_kpa: float = 9.3
    shear_slope: float = 0.11

    def normal_kpa(self, rel: np.ndarray) -> np.ndarray:
        split_rel = self.normal_slope_low * self.normal_split_kpa
        low = rel / self.normal_slope_low
        high = self.normal_split_kpa + (rel - split_rel) / self.normal_slope_high
        return np.where(rel <= split_rel, low, high)

    def normal_rel(self, kpa: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`normal_kpa` (used by the simulator)."""
        kpa = np.asarray(kpa, dtype=np.float64)
        split_rel = self.normal_slope_low * self.normal_split_kpa
        low = kpa * self.normal_slope_low
        high = split_rel + (kpa - self.normal_split_kpa) * self.normal_slope_high
        return np.where(kpa <= self.normal_split_kpa, low, high)

    def shear_kpa(self, d: np.ndarray) -> np.ndarray:
        return d / self.shear_slope


@dataclass(frozen=True)
class Layout:
    """Geometry and channel roles of one sensor kind.

    ``channels_per_taxel`` is 5 for the shear sensor and 1 for pressure-only grids.
    Taxel ``t`` owns channels ``t*k .. t*k+k-1``. ``column_major`` places taxel t at
    row ``t % rows``, column ``t // rows`` (the ShearSense wiring); otherwise row-major.
    ``falls_under_load`` is True for capacitance counts that drop when pressed; pressure
    grids (CoST, HAART) rise instead. ``shear_sign_x/y`` fix the sign of the paper's
    differential formula so that decoded shear points the way the skin is dragged.
    """

    name: str
    rows: int
    cols: int
    channels_per_taxel: int = 1
    pitch_mm: float = 10.0
    taxel_size_mm: float = 8.0
    column_major: bool = False
    falls_under_load: bool = False
    raw_dtype: str = "float32"
    raw_max: float = 65535.0
    touch_ratio: float = 0.97
    units: str = "a.u."
    shear_sign_x: float = 1.0
    shear_sign_y: float = 1.0
    outer_offset_mm: float = 4.5
    calibration: Calibration | None = None
    description: str = ""

    @property
    def n_taxels(self) -> int:
        return self.rows * self.cols

    @property
    def n_channels(self) -> int:
        return self.n_taxels * self.channels_per_taxel

    @property
    def has_shear(self) -> bool:
        return self.channels_per_taxel == 5

    @property
    def virtual_shape(self) -> tuple[int, int]:
        return (2 * self.rows - 1, 2 * self.cols - 1)

    def taxel_rc(self, taxel: int) -> tuple[int, int]:
        if self.column_major:
            return taxel % self.rows, taxel // self.rows
        return taxel // self.cols, taxel % self.cols

    def taxel_at(self, row: int, col: int) -> int:
        return col * self.rows + row if self.column_major else row * self.cols + col

    def taxel_name(self, row: int, col: int) -> str:
        """Row letter (A at the top) and 1-based column: A1 is top-left, F6 bottom-right."""
        letters = string.ascii_uppercase
        letter = letters[row] if row < 26 else letters[row // 26 - 1] + letters[row % 26]
        return f"{letter}{col + 1}"

    def channel(self, taxel: int, role: int = CENTRE) -> int:
        if self.channels_per_taxel == 1:
            return taxel
        return taxel * self.channels_per_taxel + role

    def grid_index(self) -> np.ndarray:
        """(rows, cols) array of taxel numbers, for gathering channels into a grid."""
        return _grid_index(self)

    def role_channels(self, role: int) -> np.ndarray:
        """(rows, cols) array of the raw channel index with ``role`` for every taxel."""
        return _role_channels(self, role)

    def taxel_centre_mm(self, row: int, col: int) -> tuple[float, float]:
        """(x, y) of a taxel centre in mm from the top-left taxel's centre."""
        return col * self.pitch_mm, row * self.pitch_mm

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "rows": self.rows,
            "cols": self.cols,
            "channels_per_taxel": self.channels_per_taxel,
            "pitch_mm": self.pitch_mm,
        }


@functools.lru_cache(maxsize=64)
def _grid_index(layout: Layout) -> np.ndarray:
    # Cached: decoding a single frame at display rate would otherwise rebuild it each time.
    grid = np.empty((layout.rows, layout.cols), dtype=np.int64)
    for t in range(layout.n_taxels):
        grid[layout.taxel_rc(t)] = t
    grid.setflags(write=False)
    return grid


@functools.lru_cache(maxsize=256)
def _role_channels(layout: Layout, role: int) -> np.ndarray:
    out = _grid_index(layout) * layout.channels_per_taxel + (
        role if layout.channels_per_taxel > 1 else 0)
    out.setflags(write=False)
    return out


SHEARSENSE_6X6 = Layout(
    name="shearsense-6x6",
    rows=6,
    cols=6,
    channels_per_taxel=5,
    pitch_mm=16.0,
    taxel_size_mm=14.0,
    column_major=True,
    falls_under_load=True,
    raw_dtype="uint16",
    raw_max=65535.0,
    units="kPa",
    # Raw counts fall under load. Dragging the skin towards +x loads the +x outer channel
    # more than the -x one, so its count falls further; the paper's (C_a*C_b' - C_b*C_a')
    # term with a = -x, b = +x is then negative, hence the minus sign.
    shear_sign_x=-1.0,
    shear_sign_y=-1.0,
    outer_offset_mm=4.5,
    calibration=Calibration(),
    description="Shear+normal capacitive array, 6x6 taxels x 5 channels (14 mm, 2 mm gap)",
)


def grid_layout(rows: int, cols: int, name: str | None = None, **kw: object) -> Layout:
    """A single-channel pressure grid of any size (row-major, values rise under load)."""
    if rows < 1 or cols < 1:
        raise UserError(f"grid layout needs positive rows and columns, got {rows}x{cols}")
    return Layout(name=name or f"grid-{rows}x{cols}", rows=rows, cols=cols,
                  **kw)  # type: ignore[arg-type]


COST_8X8 = grid_layout(8, 8, "cost-8x8", pitch_mm=10.0, raw_max=1023.0,
                       description="CoST mannequin-arm pressure grid, 8x8 at 135 Hz")
HAART_8X8 = grid_layout(8, 8, "haart-8x8", pitch_mm=10.0, raw_max=1023.0,
                        description="HAART: centre 8x8 of a 10x10 pressure grid at 54 Hz")
HAART_10X10 = grid_layout(10, 10, "haart-10x10", pitch_mm=10.0, raw_max=1023.0,
                          description="HAART full 10x10 pressure grid at 54 Hz")

LAYOUTS: dict[str, Layout] = {
    lay.name: lay for lay in (SHEARSENSE_6X6, COST_8X8, HAART_8X8, HAART_10X10)
}


def get_layout(name: str) -> Layout:
    """Look a layout up by name; ``grid-RxC`` builds any single-channel grid."""
    if name in LAYOUTS:
        return LAYOUTS[name]
    if name.startswith("grid-"):
        try:
            rows, cols = (int(v) for v in name[5:].split("x"))
        except ValueError:
            raise UserError(f"bad grid layout name {name!r}: expected grid-RxC, e.g. grid-8x8")
        return grid_layout(rows, cols)
    known = ", ".join(sorted(LAYOUTS)) + ", grid-RxC"
    raise UserError(f"unknown layout {name!r} (known: {known})")
