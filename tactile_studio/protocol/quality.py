"""Quality flags for one trial, computed from its raw frames when it ends.

A flag is a reason for the experimenter to look again (and usually redo the trial):

* ``no_contact``  - the sensor was touched in fewer than ``min_contact_fraction`` of frames
  (at least one)
* ``saturated``   - a count hit the end of its range (0 or 65535 for capacitance counts)
* ``stuck_channel`` - a channel did not change at all while most others did
* ``dropped_frames`` - frames of the trial were lost between device and file
* ``gap``         - the device's sequence numbers or clock jump inside the trial
* ``off_centre``  - the load centroid lies outside the sensor's centre region
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from tactile_studio.sensor.decode import contact_taxels, relative_change
from tactile_studio.sensor.layout import CENTRE, Layout
from tactile_studio.storage.trial_checks import MISMATCH_FLAG

FLAGS = ("no_contact", "saturated", "stuck_channel", "dropped_frames", "gap", "off_centre",
         "model_mismatch")
FLAG_TEXT = {
    "no_contact": "no contact",
    "saturated": "saturated counts",
    "stuck_channel": "a stuck channel",
    "dropped_frames": "dropped frames",
    "gap": "a gap in the stream",
    "off_centre": "contact off the sensor centre",
    "model_mismatch": "does not look like the prompted gesture",
}


@dataclass(frozen=True)
class QualitySettings:
    min_contact_fraction: float = 0.03  # a light poke touches ~5-15% of a 2 s trial
    centre_fraction: float = 0.7   # centre region: this share of the array's extent
    gap_factor: float = 1.8        # a device-time step over gap_factor / rate is a gap
    moving_share: float = 0.5      # stuck needs at least this share of channels moving
    contact_rel: float = 0.015     # capacitance: a channel 1.5% under baseline is touched


def trial_flags(layout: Layout, raw: np.ndarray, baseline: np.ndarray, *,
                device_time: np.ndarray | None = None, seq: np.ndarray | None = None,
                rate_hz: float | None = None, lost_frames: int = 0, gap_events: int = 0,
                settings: QualitySettings | None = None) -> list[str]:
    """The flags of a trial's frames ``raw`` (T, n_channels), in the order of FLAGS."""
    s = settings or QualitySettings()
    raw = np.asarray(raw)
    flags: set[str] = set()
    if lost_frames > 0:
        flags.add("dropped_frames")
    if gap_events > 0 or _has_gap(device_time, seq, rate_hz, s.gap_factor):
        flags.add("gap")
    if raw.ndim == 2 and raw.shape[0] > 0:
        if _saturated(layout, raw):
            flags.add("saturated")
        if _stuck(raw, s.moving_share):
            flags.add("stuck_channel")
        touching = contact_taxels(layout, raw, baseline, s.contact_rel).any(axis=(1, 2))
        if touching.sum() < max(1.0, s.min_contact_fraction * raw.shape[0]):
            flags.add("no_contact")
        else:
            centroid = load_centroid(layout, raw, baseline, s.contact_rel)
            if centroid is not None and not in_centre(layout, centroid, s.centre_fraction):
                flags.add("off_centre")
    elif lost_frames == 0:
        flags.add("dropped_frames")  # nothing to judge: the frames are gone
    return [f for f in FLAGS if f in flags]


def describe(flags: list[str], check: Mapping[str, Any] | None = None) -> str:
    """'no contact, a stuck channel' for prompts; with the trial's model ``check`` its
    flag reads as the check's reason ("looks like Wide Pinch (0.61); Twist 0.07")."""
    def text(f: str) -> str:
        if f == MISMATCH_FLAG and check and check.get("reason"):
            return str(check["reason"])
        return FLAG_TEXT.get(f, f)
    return ", ".join(text(f) for f in flags)


def _saturated(layout: Layout, raw: np.ndarray) -> bool:
    if layout.falls_under_load:
        return bool((raw <= 0).any() or (raw >= layout.raw_max).any())
    return bool((raw >= layout.raw_max).any())


def _stuck(raw: np.ndarray, moving_share: float) -> bool:
    if raw.shape[0] < 3:
        return False
    ptp = np.ptp(raw, axis=0)
    moving = ptp > 0
    return bool((~moving).any() and moving.mean() >= moving_share)


def _has_gap(device_time: np.ndarray | None, seq: np.ndarray | None, rate_hz: float | None,
             factor: float) -> bool:
    if seq is not None and len(seq) > 1:
        s = np.asarray(seq, dtype=np.int64)
        valid = (s[1:] >= 0) & (s[:-1] >= 0)
        if (np.diff(s)[valid] != 1).any():
            return True
    if device_time is not None and rate_hz and len(device_time) > 1:
        if (np.diff(np.asarray(device_time, dtype=np.float64)) > factor / rate_hz).any():
            return True
    return False


def load_centroid(layout: Layout, raw: np.ndarray, baseline: np.ndarray,
                  contact_rel: float = 0.015) -> tuple[float, float] | None:
    """(row, col) of the trial's load-weighted centroid in taxel units, None without load."""
    rel = relative_change(layout, raw, baseline)[:, layout.role_channels(CENTRE)]
    contact = contact_taxels(layout, raw, baseline, contact_rel)
    weight = (np.clip(rel, 0.0, None) * contact).sum(axis=0)
    total = float(weight.sum())
    if total <= 0:
        return None
    rows, cols = np.mgrid[0:layout.rows, 0:layout.cols]
    return float((weight * rows).sum() / total), float((weight * cols).sum() / total)


def in_centre(layout: Layout, centroid: tuple[float, float], fraction: float) -> bool:
    """True when the centroid lies in the centred box covering ``fraction`` of each axis."""
    r, c = centroid
    half_r = fraction * (layout.rows - 1) / 2.0
    half_c = fraction * (layout.cols - 1) / 2.0
    return abs(r - (layout.rows - 1) / 2.0) <= half_r and abs(c - (layout.cols - 1) / 2.0) <= half_c
