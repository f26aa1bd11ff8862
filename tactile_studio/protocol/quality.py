"""Quality flags for one trial, computed from its raw frames when it ends.

A flag is a reason for the experimenter to look again (and usually redo the trial); each
has a text a person reads at a glance (FLAG_TEXT; docs/trial-check.md):

* ``no_contact``  - the sensor was touched in fewer than ``min_contact_fraction`` of frames
  (at least one)
* ``short_contact`` - touched, but in less than the protocol's ``min_contact_share`` of
  the trial (off unless the protocol sets it: a poke is brief)
* ``saturated``   - a count hit the end of its range (0 or 65535 for capacitance counts)
* ``stuck_channel`` - a channel did not change at all while most others did
* ``dead_taxel``  - a taxel read nothing while the taxels around it were pressed
* ``dropped_frames`` - frames of the trial were lost between device and file
* ``gap``         - the device's sequence numbers or clock jump inside the trial
* ``off_centre``  - the load centroid lies outside the sensor's centre region
* ``too_light`` / ``too_heavy`` - the trial's force (90th percentile over its touched
  frames of the most loaded taxel's normal stress) outside the range of the force the
  protocol declares for the gesture (``force = "light" | "natural" | "heavy"``)
* ``release_overlap`` - the trial starts during a touch's release (loaded at its first
  frame and unloading fast): the previous gesture was still ending
* ``model_mismatch`` - the model check: it does not look like the prompted gesture
  (protocol/trial_check.py; its reason names what it looked like)
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from tactile_studio.sensor.decode import contact_taxels, decode, relative_change
from tactile_studio.sensor.layout import CENTRE, Layout
from tactile_studio.storage.format.trial_checks import MISMATCH_FLAG

if TYPE_CHECKING:
    from tactile_studio.storage.format.protocol_file import CollectionProtocol

FLAGS = ("no_contact", "short_contact", "saturated", "stuck_channel", "dead_taxel",
         "dropped_frames", "gap", "off_centre", "too_light", "too_heavy", "release_overlap",
         "model_mismatch")
FLAG_TEXT = {
    "no_contact": "no contact",
    "short_contact": "contact too short",
    "saturated": "saturated counts",
    "stuck_channel": "a stuck channel",
    "dead_taxel": "a dead taxel",
    "dropped_frames": "dropped frames",
    "gap": "a gap in the stream",
    "off_centre": "contact off the sensor centre",
    "too_light": "too light for the gesture",
    "too_heavy": "too heavy for the gesture",
    "release_overlap": "began during the previous touch's release",
    "model_mismatch": "does not look like the prompted gesture",
}
# a gesture's declared force -> the range of the trial's force (kPa) it may have. The real
# corpus: 90th-percentile peak normal 6.65 kPa per person [2.88-12.97] (docs/trial-check.md)
FORCE_RANGES_KPA: dict[str, tuple[float, float]] = {
    "light": (0.0, 6.0), "natural": (2.0, 30.0), "heavy": (5.0, 60.0)}


@dataclass(frozen=True)
class QualitySettings:
    min_contact_fraction: float = 0.03  # a light poke touches ~5-15% of a 2 s trial
    centre_fraction: float = 0.7   # centre region: this share of the array's extent
    gap_factor: float = 1.8        # a device-time step over gap_factor / rate is a gap
    moving_share: float = 0.5      # stuck needs at least this share of channels moving
    contact_rel: float = 0.015     # capacitance: a channel 1.5% under baseline is touched
    min_contact_share: float = 0.0  # short_contact below this share of frames (0: off)
    dead_share: float = 0.1        # dead: peak under this share of its pressed neighbours'


def quality_settings(protocol: CollectionProtocol) -> QualitySettings:
    """The settings a protocol (storage.protocol_file.Protocol) declares in [quality]."""
    return QualitySettings(min_contact_fraction=protocol.min_contact_fraction,
                           centre_fraction=protocol.centre_fraction,
                           min_contact_share=protocol.min_contact_share)


@dataclass(frozen=True)
class FrameTiming:
    """What the link says about a trial's frames: their device times and sequence
    numbers (None: not known), the nominal rate, frames the link lost and gap events
    the recording logged inside the trial. Left empty, no gap is looked for."""

    device_time: np.ndarray | None = None
    seq: np.ndarray | None = None
    rate_hz: float | None = None
    lost_frames: int = 0
    gap_events: int = 0


def trial_flags(layout: Layout, raw: np.ndarray, baseline: np.ndarray, *,
                timing: FrameTiming = FrameTiming(), settings: QualitySettings | None = None,
                force: str | None = None) -> list[str]:
    """The flags of a trial's frames ``raw`` (T, n_channels), in the order of FLAGS;
    ``force``: the gesture's declared force (FORCE_RANGES_KPA), None: not checked."""
    s = settings or QualitySettings()
    raw = np.asarray(raw)
    flags: set[str] = set()
    if timing.lost_frames > 0:
        flags.add("dropped_frames")
    if timing.gap_events > 0 or _has_gap(timing.device_time, timing.seq, timing.rate_hz,
                                         s.gap_factor):
        flags.add("gap")
    if raw.ndim == 2 and raw.shape[0] > 0:
        if _saturated(layout, raw):
            flags.add("saturated")
        if _stuck(raw, s.moving_share):
            flags.add("stuck_channel")
        contact = contact_taxels(layout, raw, baseline, s.contact_rel)
        touching = contact.any(axis=(1, 2))
        if touching.sum() < max(1.0, s.min_contact_fraction * raw.shape[0]):
            flags.add("no_contact")
        else:
            if touching.mean() < s.min_contact_share:
                flags.add("short_contact")
            centroid = load_centroid(layout, raw, baseline, s.contact_rel)
            if centroid is not None and not in_centre(layout, centroid, s.centre_fraction):
                flags.add("off_centre")
            flags.update(_load_flags(layout, raw, baseline, touching, s, force))
    elif timing.lost_frames == 0:
        flags.add("dropped_frames")  # nothing to judge: the frames are gone
    return [f for f in FLAGS if f in flags]


def _load_flags(layout: Layout, raw: np.ndarray, baseline: np.ndarray,
                touching: np.ndarray, s: QualitySettings, force: str | None) -> set[str]:
    """dead_taxel, too_light / too_heavy and release_overlap, from the decoded normal
    stress of a touched trial."""
    out: set[str] = set()
    normal = np.asarray(decode(layout, raw, baseline).normal, dtype=np.float64)  # (T, R, C)
    # pressed means above the noise: 3 kPa on a calibrated (kPa) sensor
    if _dead_taxel(normal.max(axis=0), s.dead_share, 3.0 if layout.has_shear else 0.0):
        out.add("dead_taxel")
    if force in FORCE_RANGES_KPA and layout.has_shear:  # kPa: a calibrated shear sensor
        lo, hi = FORCE_RANGES_KPA[force]
        level = float(np.percentile(normal.reshape(len(normal), -1).max(axis=1)[touching], 90))
        if level < lo:
            out.add("too_light")
        elif level > hi:
            out.add("too_heavy")
    load = np.clip(normal, 0.0, None).sum(axis=(1, 2))
    head = max(2, len(load) // 10)
    if touching[0] and len(load) > head and load[0] > 0 and load[head] < 0.5 * load[0] \
            and load[0] >= 0.2 * load.max():
        out.add("release_overlap")
    return out


def _dead_taxel(peak: np.ndarray, share: float, pressed_min: float) -> bool:
    """A taxel whose peak stays under ``share`` of the mean peak of its pressed
    4-neighbours (at least three of them, each clearly pressed: a quarter of the trial's
    peak and at least ``pressed_min``)."""
    rows, cols = peak.shape
    strong = max(0.25 * float(peak.max()), pressed_min)
    if strong <= 0:
        return False
    for r in range(rows):
        for c in range(cols):
            near = [peak[i, j] for i, j in ((r - 1, c), (r + 1, c), (r, c - 1), (r, c + 1))
                    if 0 <= i < rows and 0 <= j < cols]
            pressed = [v for v in near if v >= strong]
            if len(pressed) >= 3 and peak[r, c] < share * float(np.mean(pressed)):
                return True
    return False


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
