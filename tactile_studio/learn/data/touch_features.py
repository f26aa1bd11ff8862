"""Touch and shear features of one window, for the forest family (rf, et, knn).

Why: on the five real people of the development set (issue 45, /work/research FINDINGS
section 2.1) these 122 values, added to :mod:`features`' 115, gained rf 6.4 points per
performance and extra-trees 7.4 (McNemar p 0.027 / 0.004), most on Circular Stroke,
Wide Pinch, Twist and key n. They describe a touch as the CoST / HAART challenge winners
did (pressure level, contact area, temporal peaks and rhythm, spectral bands, centroid
motion) plus shear: magnitude, direction coherence and reversals, rotation of the shear
vector, curl and divergence of the shear field, shear/normal balance. Every value is a
magnitude or a rotation-free quantity, so none depends on how the grid is turned.

Computed with array operations over the whole window (no loop over frames: live
inference spends its 5 ms budget here); the values equal the research script's
(``touchfeats.py``) to float rounding. Positions are in taxel pitches of the decoded grid.
Without shear channels the shear values are those of zero shear; without a normal channel
the touch values are those of no contact.
"""

from __future__ import annotations

import numpy as np

CONTACT_KPA = 0.5  # a taxel is in contact above this normal stress
BANDS = ((0.0, 1.0), (1.0, 2.0), (2.0, 4.0), (4.0, 8.0), (8.0, np.inf))
_STAT = ("mean", "std", "p10", "p50", "p90", "max", "skew", "kurt", "mad")
_SPEC = tuple(f"b{i}" for i in range(len(BANDS))) + ("domhz", "cenhz", "sent")
_RHYTHM = ("peaks_hz", "peak_prom", "ibi_cv", "ac_max", "ac_lag")
_CENTROID = ("c_path_hz", "c_net", "c_straight", "c_major", "c_minor", "c_axis_ratio",
             "c_angvel", "c_angvel_abs", "c_rot_consist", "c_rev_hz", "gyr_mean", "gyr_std",
             "gyr_trend", "blobs_mean", "blobs_max", "blobs2_share")
_DIRECTION = ("s_dir_coh", "s_axis_ratio", "s_rev_hz", "s_angvel", "s_angvel_abs",
              "s_rot_consist")
_FIELD = ("curl_mean", "curl_absmean", "curl_std", "div_mean", "div_std")

# the one list of the names, in the order of the values (touch_features)
NAMES: tuple[str, ...] = (
    *(f"{s}_{k}" for s in ("load", "peak", "area", "smag", "snet") for k in _STAT),
    "contact_share", "onsets_hz", "seg_dur", "shear_normal", "net_over_mag",
    "peak_over_mean_contact",
    *(f"{s}_{k}" for s in ("load", "smag", "area") for k in _SPEC),
    *(f"{s}_{k}" for s in ("load", "smag") for k in _RHYTHM),
    *_CENTROID, *_DIRECTION, *_FIELD,
    *(f"smain_{k}" for k in _SPEC),
    "log_peak_p90", "log_smag_p90",
)
# one frame's 4-connected contact regions; frames never join (labelled all at once)
_FRAME_CROSS = np.zeros((3, 3, 3), dtype=bool)
_FRAME_CROSS[1] = [[0, 1, 0], [1, 1, 1], [0, 1, 0]]


def _stats(sig: np.ndarray) -> np.ndarray:
    """(k, n) signals -> (k, 9): mean, std, p10, p50, p90, max, skew, excess kurtosis,
    mean absolute first difference."""
    mean, std = sig.mean(axis=1), sig.std(axis=1)
    p10, p50, p90 = np.percentile(sig, [10, 50, 90], axis=1)
    ok = std > 1e-12
    z = np.where(ok[:, None], (sig - mean[:, None]) / np.where(ok, std, 1.0)[:, None], 0.0)
    z2 = z * z
    mad = np.abs(np.diff(sig, axis=1)).mean(axis=1) if sig.shape[1] > 1 else np.zeros(len(sig))
    return np.stack([mean, std, p10, p50, p90, sig.max(axis=1), (z2 * z).mean(axis=1),
                     (z2 * z2).mean(axis=1) - 3.0, mad], axis=1)


def _spectra(sig: np.ndarray, rate: float) -> np.ndarray:
    """(k, n) -> (k, 8): each linearly detrended, Hann-windowed power spectrum without
    DC: share of power per band, dominant and centroid frequency (Hz), normalised
    entropy. All zero for a flat or too short signal."""
    k, n = sig.shape
    out = np.zeros((k, len(_SPEC)))
    if n < 8:
        return out
    t = np.arange(n, dtype=np.float64) - (n - 1) / 2.0
    slope = (sig * t).sum(axis=1) / (t * t).sum()
    flat = sig - sig.mean(axis=1, keepdims=True) - slope[:, None] * t
    pw = np.abs(np.fft.rfft(flat * np.hanning(n), axis=1))[:, 1:] ** 2
    f = np.fft.rfftfreq(n, 1.0 / rate)[1:]
    tot = pw.sum(axis=1)
    live = tot > 1e-18
    q = pw / np.where(live, tot, 1.0)[:, None]
    bands = np.stack([(f >= a) & (f < b) for a, b in BANDS], axis=1).astype(np.float64)
    out[:, :len(BANDS)] = q @ bands
    out[:, len(BANDS)] = f[pw.argmax(axis=1)]
    out[:, len(BANDS) + 1] = q @ f
    out[:, len(BANDS) + 2] = -(q * np.log(q + 1e-12)).sum(axis=1) / np.log(len(f))
    out[~live] = 0.0
    return out


def _rhythm(sig: np.ndarray, rate: float) -> list[float]:
    """Peaks per second, their mean prominence over the range, the CV of the intervals
    between them, and the autocorrelation's strongest repeat in 0.15-2 s (value, lag s)."""
    from scipy.signal import find_peaks

    n = len(sig)
    rng = float(sig.max() - sig.min())
    out = [0.0] * len(_RHYTHM)
    if n < 8 or rng <= 1e-9:
        return out
    pk, props = find_peaks(sig, prominence=0.2 * rng, distance=max(1, int(0.08 * rate)))
    out[0] = len(pk) / (n / rate)
    if len(pk):
        out[1] = float(np.mean(props["prominences"]) / rng)
    if len(pk) > 2:
        ibi = np.diff(pk)
        out[2] = float(ibi.std() / ibi.mean())
    z = sig - sig.mean()
    ac = np.correlate(z, z, "full")[n - 1:]
    lo, hi = max(1, int(0.15 * rate)), min(n - 1, int(2.0 * rate))
    if ac[0] > 0 and hi > lo:
        j = lo + int(np.argmax(ac[lo:hi]))
        out[3], out[4] = float(ac[j] / ac[0]), j / rate
    return out


def _centroid(load: np.ndarray, contact: np.ndarray, idx: np.ndarray, n: int,
              rate: float) -> list[float]:
    """The load-weighted centroid's path over the contact frames ``idx``, its spread and
    rotation, back-and-forth reversals, the radius of gyration and contact blobs."""
    from scipy.ndimage import label

    if len(idx) < 3:
        return [0.0] * len(_CENTROID)
    rows, cols = load.shape[1:]
    yy, xx = np.mgrid[0:rows, 0:cols].astype(np.float64)
    wl = load[idx]
    tot = wl.sum(axis=(1, 2)) + 1e-9
    cy = (wl * yy).sum(axis=(1, 2)) / tot
    cx = (wl * xx).sum(axis=(1, 2)) / tot
    cont = np.diff(idx) == 1
    path = float(np.hypot(np.diff(cx), np.diff(cy))[cont].sum())
    seconds = n / rate
    net = float(np.hypot(cx[-1] - cx[0], cy[-1] - cy[0]))
    evals, evecs = np.linalg.eigh(np.cov(np.vstack([cx, cy])) + 1e-12 * np.eye(2))
    major, minor = float(np.sqrt(max(evals[1], 0))), float(np.sqrt(max(evals[0], 0)))
    dang = np.diff(np.unwrap(np.arctan2(cy - cy.mean(), cx - cx.mean())))[cont]
    dur = len(idx) / rate
    turn, turn_abs = abs(dang.sum()), np.abs(dang).sum()
    dp = np.diff(evecs[:, -1] @ np.vstack([cx, cy]))[cont]
    dp = dp[np.abs(dp) > 0.02]
    rev = float((np.diff(np.sign(dp)) != 0).sum() / seconds) if len(dp) > 1 else 0.0
    gyr = np.sqrt((wl * ((yy - cy[:, None, None]) ** 2 + (xx - cx[:, None, None]) ** 2)
                   ).sum(axis=(1, 2)) / tot)
    third = max(1, len(gyr) // 3)
    # components numbered frame by frame: a frame's count is its rise of the running max
    labels = label(contact[idx[::max(1, len(idx) // 40)]], structure=_FRAME_CROSS)[0]
    blobs = np.diff(np.maximum.accumulate(labels.max(axis=(1, 2))), prepend=0)
    return [path / seconds, net, net / max(path, 1e-9), major, minor,
            minor / max(major, 1e-9), turn / dur, turn_abs / dur,
            turn / max(turn_abs, 1e-9), rev, float(gyr.mean()), float(gyr.std()),
            float(gyr[-third:].mean() - gyr[:third].mean()), float(blobs.mean()),
            float(blobs.max()), float((blobs >= 2).mean())]


def _direction(vx: np.ndarray, vy: np.ndarray, net: np.ndarray, n: int,
               rate: float) -> list[float]:
    """The net shear vector over its strong frames: direction coherence, axis ratio,
    reversals along its main axis per second, its rotation."""
    strong = net > max(0.2 * net.max(), 1e-6)
    if strong.sum() < 3:
        return [0.0] * len(_DIRECTION)
    coh = float(np.hypot(vx[strong].sum(), vy[strong].sum()) / net[strong].sum())
    ev, evecs = np.linalg.eigh(np.cov(np.vstack([vx, vy])) + 1e-12 * np.eye(2))
    proj = evecs[:, -1] @ np.vstack([vx, vy])
    proj = proj - np.median(proj)
    sgn = np.sign(proj[np.abs(proj) > 0.2 * np.abs(proj).max()])
    dth = np.diff(np.unwrap(np.arctan2(vy[strong], vx[strong])))
    dur = strong.sum() / rate
    turn, turn_abs = abs(dth.sum()), np.abs(dth).sum()
    return [coh, float(np.sqrt(max(ev[0], 0) / max(ev[1], 1e-12))),
            float((np.diff(sgn) != 0).sum() / (n / rate)), turn / dur, turn_abs / dur,
            turn / max(turn_abs, 1e-9)]


def touch_features(x: np.ndarray, channel_names: list[str], rate: float) -> np.ndarray:
    """The 122 values (``NAMES``' order) of one window ``x`` (C, N, R, X) in kPa."""
    ch = {name: np.asarray(x[i], dtype=np.float64) for i, name in enumerate(channel_names)}
    some = next(iter(ch.values()))
    zero = np.zeros_like(some)
    normal = ch.get("normal", ch.get("pressure", zero))
    sx, sy = ch.get("shear_x", zero), ch.get("shear_y", zero)
    n = normal.shape[0]
    load = np.clip(normal, 0, None)
    mag = np.hypot(sx, sy)
    contact = normal > CONTACT_KPA
    total, peak = load.sum(axis=(1, 2)), load.max(axis=(1, 2))
    area = contact.sum(axis=(1, 2)).astype(np.float64)
    smag = mag.sum(axis=(1, 2))
    vx, vy = sx.sum(axis=(1, 2)), sy.sum(axis=(1, 2))
    net = np.hypot(vx, vy)
    active = area > 0
    w = active if active.any() else np.ones(n, bool)
    onsets = int((np.diff(active.astype(np.int8)) == 1).sum()) + int(active[0])
    balance = [float(active.mean()), onsets / (n / rate),
               float(active.sum() / rate / max(onsets, 1)),
               float(smag[w].sum() / max(total[w].sum(), 1e-9)),
               float(net[w].sum() / max(smag[w].sum(), 1e-9)),
               float(peak[w].mean() / max((total[w] / np.maximum(area[w], 1)).mean(), 1e-9))]
    # field structure: load-weighted curl (twist) and divergence (pinch) per frame
    div = np.gradient(sx, axis=2) + np.gradient(sy, axis=1)
    curl = np.gradient(sy, axis=2) - np.gradient(sx, axis=1)
    wsum = total + 1e-9
    curl_t, div_t = (curl * load).sum(axis=(1, 2)) / wsum, (div * load).sum(axis=(1, 2)) / wsum
    scale = max(float(mag[contact].mean()) if contact.any() else 0.0, 1e-6)
    field = [abs(curl_t[w].mean()) / scale, np.abs(curl_t[w]).mean() / scale,
             curl_t[w].std() / scale, div_t[w].mean() / scale, div_t[w].std() / scale]
    main = vx if np.var(vx) > np.var(vy) else vy  # rubs oscillate along it, strokes sweep
    spectra = _spectra(np.stack([total, smag, area, main]), rate)
    values = np.concatenate([
        _stats(np.stack([total, peak, area, smag, net])).ravel(), balance,
        spectra[:3].ravel(), _rhythm(total, rate), _rhythm(smag, rate),
        _centroid(load, contact, np.flatnonzero(active), n, rate),
        _direction(vx, vy, net, n, rate), field, spectra[3],
        [np.log1p(np.percentile(peak, 90)), np.log1p(np.percentile(smag, 90))]])
    return np.nan_to_num(values.astype(np.float64))
