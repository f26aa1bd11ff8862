"""The shear paper's per-trial gesture metrics (mean normal stress, mean |shear|, contact
area, dominant frequency, movement type), computed on one decoded trial ``(C, N, R, X)``.

They describe how a gesture was performed, so exports, reports and the learning features
all use them; they live with the sensor maths because nothing here is about learning.
"""

from __future__ import annotations

import numpy as np

MOVEMENT_TYPES = ("static", "transversal", "convergent", "divergent")
# Movement-type thresholds, in physical taxel pitches and seconds (see gesture_metrics).
SPREAD_THRESHOLD = 0.3     # relative change of the contact's radius of gyration ...
SPREAD_MIN_PITCH = 0.25    # ... that is also at least this many pitches
TRAVEL_THRESHOLD = 3.0     # pitch/s speed of the pressure centroid


SPECTRAL_NAMES = ("band1", "band2", "band3", "band4", "dominant_hz", "centroid_hz")


def spectral_summary(sig: np.ndarray, rate: float) -> list[float]:
    """Share of non-DC spectral energy in four equal bands up to Nyquist, the dominant
    frequency and the spectral centroid (Hz), in the order of ``SPECTRAL_NAMES``."""
    if len(sig) < 4:
        return [0.0] * len(SPECTRAL_NAMES)
    power = np.abs(np.fft.rfft(sig - sig.mean())) ** 2
    freqs = np.fft.rfftfreq(len(sig), 1.0 / rate)
    power, freqs = power[1:], freqs[1:]
    total = power.sum()
    if total <= 1e-18:
        return [0.0] * len(SPECTRAL_NAMES)
    edges = np.linspace(0, freqs[-1] + 1e-9, 5)
    bands = [float(power[(freqs >= a) & (freqs < b)].sum() / total)
             for a, b in zip(edges[:-1], edges[1:])]
    return bands + [float(freqs[power.argmax()]), float((freqs * power).sum() / total)]


def dominant_frequency(sig: np.ndarray, rate: float) -> float:
    """Frequency (Hz) of the largest non-DC spectral peak; 0 for a too-short signal."""
    return spectral_summary(sig, rate)[4]


def gesture_metrics(x: np.ndarray, channel_names: list[str], rate: float,
                    cell_pitch: float = 1.0) -> dict[str, float | str]:
    """The shear paper's per-trial gesture metrics.

    Contact: a cell is in contact when its load exceeds 10% of the trial's peak load
    (load = normal stress, or |shear| when only shear is given); the
    *active* frames are those whose total contact load exceeds 25% of the trial's peak.

    * ``mean_normal`` / ``mean_abs_shear``: means over contact cells and frames;
    * ``contact_area``: mean fraction of the grid in contact over active frames;
    * ``dominant_hz``: dominant frequency of the total load (the gesture's speed);
    * ``centroid_speed``: path length of the load-weighted centroid over active frames per
      second, in physical taxel pitches (``cell_pitch`` is 0.5 on the virtual grid);
    * ``spread_change``: relative change of the contact's radius of gyration from the
      first to the last third of the active frames (negative: contacts draw together);
    * ``divergence`` / ``curl``: contact-weighted mean divergence / curl of the shear field
      (finite differences, per pitch) divided by the mean |shear|;
    * ``coherence``: |mean shear vector| / mean |shear| (1 = all dragged one way).

    Movement type: ``convergent`` if spread_change < -0.3 and the radius shrank by at
    least 0.25 pitch, ``divergent`` if > +0.3 and it grew by 0.25 pitch, otherwise
    ``transversal`` if the centroid travels faster than 3 pitch/s, otherwise
    ``static``. The shear divergence is reported but does not decide the type: on this
    sensor a pressure gradient alone reads as inward shear around every contact (the
    outer channels facing the load are pressed harder), which biases the divergence
    negative for every gesture.
    """
    ch = {name: x[i].astype(np.float64) for i, name in enumerate(channel_names)}
    normal = ch.get("normal", ch.get("pressure"))
    sx, sy = ch.get("shear_x"), ch.get("shear_y")
    mag = np.hypot(sx, sy) if sx is not None and sy is not None else None
    load = np.clip(normal, 0, None) if normal is not None else mag
    n = load.shape[0]
    thr = max(0.1 * float(load.max()), 1e-9)
    contact = load > thr
    weight = np.where(contact, load, 0.0)
    total = weight.sum(axis=(1, 2))
    active = total > 0.25 * total.max() if total.max() > 0 else np.zeros(n, dtype=bool)
    out: dict[str, float | str] = {}
    if normal is not None:
        out["mean_normal"] = float(normal[contact].mean()) if contact.any() else 0.0
    if mag is not None:
        out["mean_abs_shear"] = float(mag[contact].mean()) if contact.any() else 0.0
    out["contact_area"] = float(contact[active].mean()) if active.any() else 0.0
    out["dominant_hz"] = dominant_frequency(total, rate)
    speed, spread, spread_abs = _centroid_motion(weight, total, active, rate, cell_pitch)
    out["centroid_speed"], out["spread_change"] = speed, spread
    if mag is not None:
        out.update(_shear_field(sx, sy, weight, contact, float(out["mean_abs_shear"]),
                                cell_pitch))
    out["movement"] = movement_type(spread, spread_abs, speed)
    return out


def _centroid_motion(weight: np.ndarray, total: np.ndarray, active: np.ndarray, rate: float,
                     cell_pitch: float) -> tuple[float, float, float]:
    """Over the active frames: the load centroid's speed (pitch/s), the relative and the
    absolute change of the contact's radius of gyration (first third to last third);
    zeros with fewer than 3 active frames."""
    rows, cols = weight.shape[1:]
    yy, xx = np.mgrid[0:rows, 0:cols].astype(np.float64) * cell_pitch
    w, wt = weight[active], total[active]
    if len(w) < 3:
        return 0.0, 0.0, 0.0
    cy = (w * yy).sum(axis=(1, 2)) / wt
    cx = (w * xx).sum(axis=(1, 2)) / wt
    gyr = np.sqrt((w * ((yy - cy[:, None, None]) ** 2 + (xx - cx[:, None, None]) ** 2))
                  .sum(axis=(1, 2)) / wt)
    frames = np.flatnonzero(active)
    duration = max((frames[-1] - frames[0]) / rate, 1.0 / rate)
    step = np.hypot(np.diff(cx), np.diff(cy))[np.diff(frames) == 1]
    third = max(1, len(gyr) // 3)
    first, last = gyr[:third].mean(), gyr[-third:].mean()
    return (float(step.sum() / duration), float((last - first) / max(first, last, 1e-9)),
            float(abs(last - first)))


def _shear_field(sx: np.ndarray, sy: np.ndarray, weight: np.ndarray, contact: np.ndarray,
                 mean_abs_shear: float, cell_pitch: float) -> dict[str, float]:
    """Contact-weighted divergence and curl of the shear field, and its coherence, each
    relative to the mean |shear|."""
    div = np.gradient(sx, cell_pitch, axis=2) + np.gradient(sy, cell_pitch, axis=1)
    curl = np.gradient(sy, cell_pitch, axis=2) - np.gradient(sx, cell_pitch, axis=1)
    wsum = weight.sum()
    scale = max(mean_abs_shear, 1e-9)
    vx = float(sx[contact].mean()) if contact.any() else 0.0
    vy = float(sy[contact].mean()) if contact.any() else 0.0
    return {"divergence": float((div * weight).sum() / wsum / scale) if wsum > 0 else 0.0,
            "curl": float((curl * weight).sum() / wsum / scale) if wsum > 0 else 0.0,
            "coherence": float(np.hypot(vx, vy) / scale)}


def movement_type(spread: float, spread_abs: float, speed: float) -> str:
    """convergent / divergent by the contact's spread, else transversal by the centroid's
    speed, else static (thresholds above; see gesture_metrics)."""
    if spread < -SPREAD_THRESHOLD and spread_abs >= SPREAD_MIN_PITCH:
        return "convergent"
    if spread > SPREAD_THRESHOLD and spread_abs >= SPREAD_MIN_PITCH:
        return "divergent"
    if speed > TRAVEL_THRESHOLD:
        return "transversal"
    return "static"
