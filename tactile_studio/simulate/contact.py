"""Contact mechanics: stress at each sensing point from a few contact patches.

A patch is a fingertip, a thumb pad or a palm pressing on the skin. What the electrodes
feel is the stress at the electrode plane under a few millimetres of elastomer, which
spreads the load: so each patch gives a smooth, flat-topped bump (flat over the core of
a palm, rounded for a fingertip) instead of a hard-edged Hertz disc. The spread also
guarantees that a fingertip anywhere on the surface reaches at least one channel, as
on the real sensor.

Shear traction is carried by the same footprint: a patch drags the skin with a uniform
traction (``shear_x/y``) plus an optional rotational one (``twist``, kPa at the patch
radius, positive turns +x towards +y).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tactile_studio.sensor.layout import CENTRE, X_NEG, X_POS, Y_NEG, Y_POS, Layout

SPREAD_MM = 4.0        # elastomer spread of a point load at the electrode plane
SPREAD_PER_MM = 0.1    # larger patches have softer edges (fleshier contact)

_ROLE_OFFSETS = {Y_NEG: (0.0, -1.0), X_NEG: (-1.0, 0.0), CENTRE: (0.0, 0.0),
                 X_POS: (1.0, 0.0), Y_POS: (0.0, 1.0)}


@dataclass
class Contacts:
    """Contact patches over a batch of frames: every array is (n_frames, n_patches).

    Positions in mm on the sensor surface, ``radius`` in mm (>= 1000 mm acts as a uniform
    load over the whole sensor), ``load`` the peak normal stress in kPa (0 = lifted),
    ``shear_x/y`` and ``twist`` tractions in kPa.
    """

    x: np.ndarray
    y: np.ndarray
    radius: np.ndarray
    load: np.ndarray
    shear_x: np.ndarray
    shear_y: np.ndarray
    twist: np.ndarray

    @property
    def n_patches(self) -> int:
        return int(self.x.shape[1])

    @classmethod
    def make(cls, n: int, x, y, radius, load, shear_x=0.0, shear_y=0.0,
             twist=0.0) -> Contacts:
        """One patch, every argument a scalar or an (n,) array."""
        def col(v) -> np.ndarray:
            return np.broadcast_to(np.asarray(v, dtype=np.float64), (n,))[:, None].copy()
        return cls(col(x), col(y), col(radius), col(load), col(shear_x), col(shear_y),
                   col(twist))

    @classmethod
    def join(cls, parts: list[Contacts]) -> Contacts:
        """Patches side by side (several fingers at once)."""
        return cls(*(np.concatenate([getattr(p, f) for p in parts], axis=1)
                     for f in ("x", "y", "radius", "load", "shear_x", "shear_y", "twist")))


def channel_points(layout: Layout) -> np.ndarray:
    """(n_channels, 2) x, y in mm of every channel's sensing point.

    The centre channel sits at the taxel centre; the outer ones are ``outer_offset_mm``
    away towards the side they face. Single-channel layouts use the taxel centres.
    """
    k = layout.channels_per_taxel
    pts = np.zeros((layout.n_channels, 2))
    for t in range(layout.n_taxels):
        cx, cy = layout.taxel_centre_mm(*layout.taxel_rc(t))
        for role in range(k):
            dx, dy = _ROLE_OFFSETS[role] if k == 5 else (0.0, 0.0)
            pts[t * k + role] = (cx + dx * layout.outer_offset_mm, cy + dy * layout.outer_offset_mm)
    return pts


def profile(dist: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Fraction of the peak stress at ``dist`` mm from a patch of ``radius`` mm.

    Flat (1.0) over the core ``radius - s`` and a Gaussian skirt of width ``s`` beyond
    it, with ``s`` the elastomer spread growing a little with patch size.
    """
    s = SPREAD_MM + SPREAD_PER_MM * radius
    u = np.maximum(dist - np.maximum(radius - s, 0.0), 0.0) / s
    return np.exp(-0.5 * u * u)


def stress_fields(contacts: Contacts, points: np.ndarray,
                  shear_idx: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Normal stress at every point and shear traction at the points ``shear_idx``.

    Returns ``normal`` (n, n_points) and ``shear_x``, ``shear_y`` (n, len(shear_idx)),
    all in kPa. Patches add up (several fingers).
    """
    n, p = contacts.x.shape
    if p == 0:
        z = np.zeros((n, len(points)))
        return z, np.zeros((n, len(shear_idx))), np.zeros((n, len(shear_idx)))
    dx = points[None, None, :, 0] - contacts.x[:, :, None]       # (n, P, M)
    dy = points[None, None, :, 1] - contacts.y[:, :, None]
    g = profile(np.hypot(dx, dy), contacts.radius[:, :, None])
    normal = np.einsum("np,npm->nm", contacts.load, g)
    gs, sdx, sdy = g[:, :, shear_idx], dx[:, :, shear_idx], dy[:, :, shear_idx]
    rot = contacts.twist[:, :, None] / contacts.radius[:, :, None]
    sx = np.einsum("np,npm->nm", contacts.shear_x, gs) - np.sum(rot * sdy * gs, axis=1)
    sy = np.einsum("np,npm->nm", contacts.shear_y, gs) + np.sum(rot * sdx * gs, axis=1)
    return normal, sx, sy
