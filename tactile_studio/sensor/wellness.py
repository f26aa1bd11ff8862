"""Wellness-check maths: what a rest phase and a known weight say about a sensor.

Qt-free and device-free: every function takes raw frames (N, n_channels) and returns
numbers and verdicts with their reasons in words. The procedure that collects the frames
(rest, place, settle, record, lift) is :mod:`tactile_studio.health.wellness`.

Verdicts are ``pass`` < ``warn`` < ``fail``; the sensor's verdict is its worst spot or
channel. Thresholds are in :class:`Thresholds` so a lab can tune them in one place.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.sensor.decode import decode, relative_change
from tactile_studio.sensor.layout import CENTRE, Layout
from tactile_studio.sensor.taxels import parse_taxel as _parse_taxel
from tactile_studio.sensor.taxels import taxel_label as _taxel_label

PASS, WARN, FAIL = "pass", "warn", "fail"
_RANK = {PASS: 0, WARN: 1, FAIL: 2}
G = 9.80665  # m/s^2
DEFAULT_SPOTS = ("B2", "B5", "E2", "E5", "C3")


def worst(verdicts: list[str] | tuple[str, ...]) -> str:
    """The worst of some verdicts (pass when there are none)."""
    return max(verdicts, key=_RANK.__getitem__, default=PASS)


@dataclass(frozen=True)
class Thresholds:
    """When a number becomes a warning or a failure (relative values are fractions)."""

    noisy_factor: float = 3.0          # channel noise vs the sensor's median channel
    stuck_ptp_counts: float = 0.0      # a channel that never moves by more than this
    saturated_fraction: float = 0.5    # share of rest frames at the rail
    dead_level: float = 0.01           # baseline below this fraction of the median
    baseline_warn: float = 0.05        # shift against the reference baseline
    baseline_fail: float = 0.15
    drift_warn_per_min: float = 0.01   # relative baseline change per minute at rest
    ratio_warn_low: float = 0.8        # spot sensitivity vs reference
    ratio_fail_low: float = 0.5
    ratio_warn_high: float = 1.25
    ratio_fail_high: float = 1.6
    dead_ratio: float = 0.1            # a loaded channel giving less than this is dead
    shear_warn: float = 0.08           # |shear| / normal under a pure normal load
    shear_fail: float = 0.15


def stress_kpa(mass_g: float, contact_mm: float) -> float:
    """Normal stress of a weight resting on a square contact of side ``contact_mm``."""
    if mass_g <= 0 or contact_mm <= 0:
        raise UserError(f"weight {mass_g:g} g on {contact_mm:g} mm: both must be positive")
    return mass_g * 1e-3 * G / (contact_mm * 1e-3) ** 2 / 1e3


# the one taxel parser (names or indices) and namer, re-exported where callers look
parse_taxel = _parse_taxel
taxel_label = _taxel_label


def channel_label(layout: Layout, channel: int) -> str:
    """'E5/centre' style name of a raw channel, for reasons in words."""
    k = layout.channels_per_taxel
    roles = ("-y", "-x", "centre", "+x", "+y") if k == 5 else ("",)
    taxel, role = divmod(channel, k)
    return f"{taxel_label(layout, taxel)}/{roles[role]}".rstrip("/")


# ---- rest phase ------------------------------------------------------------------------
@dataclass
class RestResult:
    """Per-channel statistics of the unloaded sensor."""

    baseline: np.ndarray
    noise: np.ndarray                   # counts, std of frame-to-frame change / sqrt 2
    drift_per_min: np.ndarray           # relative baseline change per minute
    shift: np.ndarray | None            # relative shift against the reference baseline
    dead: list[int] = field(default_factory=list)
    stuck: list[int] = field(default_factory=list)
    noisy: list[int] = field(default_factory=list)
    saturated: list[int] = field(default_factory=list)
    reasons: list[tuple[str, str]] = field(default_factory=list)  # (verdict, words)

    @property
    def verdict(self) -> str:
        return worst([v for v, _ in self.reasons])


def analyse_rest(layout: Layout, raw: np.ndarray, rate_hz: float,
                 reference_baseline: np.ndarray | None = None,
                 th: Thresholds = Thresholds()) -> RestResult:
    """Noise, dead, stuck and saturated channels, drift and baseline shift at rest."""
    raw = np.asarray(raw, dtype=np.float64)
    if raw.ndim != 2 or raw.shape[0] < 10:
        raise UserError("the rest phase needs at least 10 frames")
    base = raw.mean(axis=0)
    noise = np.diff(raw, axis=0).std(axis=0) / np.sqrt(2.0)
    t_min = np.arange(len(raw)) / rate_hz / 60.0
    slope = np.polyfit(t_min, raw, 1)[0] if len(raw) > 2 else np.zeros(raw.shape[1])
    safe = np.where(np.abs(base) < 1e-9, 1.0, base)
    drift = slope / safe
    out = RestResult(base, noise, drift, None)
    ptp = np.ptp(raw, axis=0)
    median_base = float(np.median(base))
    rail = (raw <= 0) | (raw >= layout.raw_max)
    out.saturated = _idx(rail.mean(axis=0) > th.saturated_fraction)
    out.dead = _idx((base < th.dead_level * median_base) & ~rail.all(axis=0))
    moving = float(np.median(ptp)) > th.stuck_ptp_counts
    out.stuck = [c for c in _idx(ptp <= th.stuck_ptp_counts) if moving
                 and c not in out.saturated and c not in out.dead]
    ref_noise = float(np.median(noise))
    out.noisy = _idx(noise > th.noisy_factor * max(ref_noise, 1e-9))
    for kind, chans, words in (
            ("dead", out.dead, "reads zero at rest — broken connection?"),
            ("stuck", out.stuck, "stuck at one value — channel not updating?"),
            ("saturated", out.saturated, "at the rail at rest — shorted or overloaded?")):
        for c in chans:
            out.reasons.append((FAIL, f"channel {c} ({channel_label(layout, c)}): {words}"))
    for c in out.noisy:
        out.reasons.append((FAIL, f"channel {c} ({channel_label(layout, c)}): noise "
                                  f"{noise[c]:.0f} counts, {noise[c] / ref_noise:.1f}x the "
                                  "sensor's typical — loose contact or interference?"))
    # a slope is only drift when it stands out of the noise (5 standard errors)
    spread = float(np.sqrt(((t_min - t_min.mean()) ** 2).sum())) or 1.0
    significant = np.abs(slope) > 5.0 * noise * np.sqrt(2.0) / spread
    out.drift_per_min = drift = np.where(significant, drift, 0.0)
    worst_drift = int(np.argmax(np.abs(drift)))
    if abs(drift[worst_drift]) > th.drift_warn_per_min:
        out.reasons.append((WARN, f"channel {worst_drift} ({channel_label(layout, worst_drift)})"
                                  f": baseline drifting {drift[worst_drift] * 100:+.1f}%/min "
                                  "— not warmed up, or temperature changing?"))
    if reference_baseline is not None and len(reference_baseline) == len(base):
        ref = np.where(np.abs(reference_baseline) < 1e-9, 1.0, reference_baseline)
        out.shift = (base - ref) / ref
        for c in _idx(np.abs(out.shift) > th.baseline_warn):
            if c in out.dead or c in out.saturated:
                continue
            verdict = FAIL if abs(out.shift[c]) > th.baseline_fail else WARN
            out.reasons.append((verdict, f"channel {c} ({channel_label(layout, c)}): baseline "
                                         f"{out.shift[c] * 100:+.0f}% from the reference"))
    return out


def _idx(mask: np.ndarray) -> list[int]:
    return [int(i) for i in np.nonzero(mask)[0]]


# ---- placement and settling ------------------------------------------------------------
def normal_map(layout: Layout, raw: np.ndarray, baseline: np.ndarray) -> np.ndarray:
    """(N, rows, cols) normal stress (nominal calibration) of some frames."""
    return decode(layout, raw, baseline).normal


def contact_taxel(layout: Layout, grid: np.ndarray, threshold_kpa: float) -> int | None:
    """The taxel nearest the contact centroid of one (rows, cols) stress map, or None.

    The centroid is weighted by stress over taxels above ``threshold_kpa`` and above a
    third of the peak, so a weight's skirt on its neighbours does not pull it aside.
    """
    peak = float(grid.max())
    if peak < threshold_kpa:
        return None
    w = np.where(grid >= max(threshold_kpa, peak / 3.0), grid, 0.0)
    rows, cols = np.indices(grid.shape)
    r = float((w * rows).sum() / w.sum())
    c = float((w * cols).sum() / w.sum())
    return layout.taxel_at(int(round(r)), int(round(c)))


def is_settled(series: np.ndarray, rate_hz: float, window_s: float = 1.0,
               tolerance_per_s: float = 0.01) -> bool:
    """True when the last ``window_s`` of a loaded signal changes by less than
    ``tolerance_per_s`` of its level per second (viscoelastic creep has died down)."""
    n = max(3, int(round(window_s * rate_hz)))
    if len(series) < n:
        return False
    tail = np.asarray(series[-n:], dtype=np.float64)
    level = abs(float(tail.mean()))
    if level < 1e-9:
        return True
    slope = np.polyfit(np.arange(n) / rate_hz, tail, 1)[0]
    return abs(slope) / level < tolerance_per_s


# ---- loaded spot -----------------------------------------------------------------------
@dataclass
class SpotResult:
    taxel: str
    normal_kpa: float
    delta_c: float                     # dC/C0 of the centre channel
    shear_kpa: float                   # |shear| read under the pure normal load
    channel_response: list[float]      # dC/C0 of each of the taxel's channels
    expected_kpa: float
    reference_kpa: float | None = None
    ratio: float | None = None
    verdict: str = PASS
    reasons: list[str] = field(default_factory=list)
    dead_channels: list[int] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return {"taxel": self.taxel, "normal_kpa": round(self.normal_kpa, 4),
                "delta_c": round(self.delta_c, 6), "shear_kpa": round(self.shear_kpa, 4),
                "ratio": None if self.ratio is None else round(self.ratio, 4),
                "expected_kpa": round(self.expected_kpa, 4),
                "reference_kpa": self.reference_kpa, "verdict": self.verdict,
                "reasons": self.reasons, "dead_channels": self.dead_channels}


def measure_spot(layout: Layout, raw: np.ndarray, baseline: np.ndarray, taxel: int,
                 expected_kpa: float) -> SpotResult:
    """Mean response of ``taxel`` over settled loaded frames."""
    frames = decode(layout, raw, baseline)
    r, c = layout.taxel_rc(taxel)
    rel = relative_change(layout, raw, baseline).mean(axis=0)
    k = layout.channels_per_taxel
    sx = float(frames.shear_x[:, r, c].mean()) if frames.shear_x is not None else 0.0
    sy = float(frames.shear_y[:, r, c].mean()) if frames.shear_y is not None else 0.0
    return SpotResult(
        taxel=taxel_label(layout, taxel), normal_kpa=float(frames.normal[:, r, c].mean()),
        delta_c=float(rel[layout.channel(taxel, CENTRE)]), shear_kpa=float(np.hypot(sx, sy)),
        channel_response=[float(v) for v in rel[taxel * k:(taxel + 1) * k]],
        expected_kpa=float(expected_kpa))


def judge_spots(layout: Layout, spots: list[SpotResult],
                th: Thresholds = Thresholds()) -> None:
    """Fill each spot's ratio, verdict, reasons and dead channels (in place).

    Reference per spot: ``reference_kpa`` when the sensor has one (its active calibration,
    else its first passing check with the same weight), else the weight's nominal stress.
    A channel is dead when it gives less than ``dead_ratio`` of the median response of the
    same-role channels on the other spots.
    """
    k = layout.channels_per_taxel
    responses = np.array([s.channel_response for s in spots])
    typical = np.median(responses, axis=0) if len(spots) else np.zeros(k)
    for s in spots:
        ref = s.reference_kpa if s.reference_kpa else s.expected_kpa
        # rounded as reported, so the reason's percentage and the report's ratio agree
        s.ratio = round(s.normal_kpa / ref, 4) if ref > 0 else None
        taxel = parse_taxel(layout, s.taxel)
        sheared = s.normal_kpa > 0.5 * s.expected_kpa and s.shear_kpa > th.shear_warn * s.normal_kpa
        # under shear the outer channels move apart: a low one is then not a dead one
        low = [role for role in range(k) if typical[role] > 0 and not sheared
               and abs(s.channel_response[role]) < th.dead_ratio * typical[role]]
        s.dead_channels = [taxel * k + role for role in low]
        verdicts = []
        if s.ratio is not None and s.ratio < th.dead_ratio:
            verdicts.append(FAIL)
            s.reasons.append(f"{s.taxel}: no response to the weight "
                             f"({s.ratio * 100:.0f}% of reference) — dead taxel?")
        elif s.ratio is not None and s.ratio < th.ratio_warn_low:
            verdicts.append(FAIL if s.ratio < th.ratio_fail_low else WARN)
            s.reasons.append(f"{s.taxel}: {s.ratio * 100:.0f}% of reference sensitivity"
                             " — worn?")
        elif s.ratio is not None and s.ratio > th.ratio_warn_high:
            verdicts.append(FAIL if s.ratio > th.ratio_fail_high else WARN)
            s.reasons.append(f"{s.taxel}: {s.ratio * 100:.0f}% of reference sensitivity"
                             " — skin stiffened, or a heavier weight than stated?")
        if s.dead_channels and (s.ratio is None or s.ratio >= th.dead_ratio):
            verdicts.append(FAIL)
            names = ", ".join(channel_label(layout, c) for c in s.dead_channels)
            s.reasons.append(f"{s.taxel}: channel(s) {names} do not respond — broken?")
        if s.normal_kpa > 0.5 * s.expected_kpa:
            share = s.shear_kpa / s.normal_kpa
            if share > th.shear_warn:
                verdicts.append(FAIL if share > th.shear_fail else WARN)
                s.reasons.append(f"{s.taxel}: reads {s.shear_kpa:.2f} kPa shear under a pure "
                                 f"normal load ({share * 100:.0f}% of normal) — delaminated "
                                 "or misaligned?")
        s.verdict = worst(verdicts)
