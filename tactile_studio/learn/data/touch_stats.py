"""Population statistics of decoded trials: how hard, how large and how sheared people's
touches are, per trial, and how much participants differ.

These are the figures the simulator's difficulty is calibrated to (issue 15's table,
measured on the real ShearSense recordings decoded with the project's own ``decode``,
physical grid, one value per labelled performance):

* ``peak_normal_p90`` — 90th percentile over frames of the frame's highest taxel normal
  stress (kPa);
* ``taxels_above`` — taxels above 0.5 kPa, mean over frames;
* ``peak_shear_p90`` — 90th percentile over frames of the highest taxel |shear| (kPa);
* ``shear_normal`` — ``peak_shear_p90 / peak_normal_p90``;
* ``contact`` — share of frames with at least one taxel above 0.5 kPa.

Each is summarised as median [IQR] over trials and a CV: the spread (std / mean) of the
participants' medians.
"""

from __future__ import annotations

from typing import Any

import numpy as np

CONTACT_KPA = 0.5
STAT_NAMES = ("peak_normal_p90", "taxels_above", "peak_shear_p90", "shear_normal", "contact")
LABELS = {
    "peak_normal_p90": "90th-percentile peak normal stress, kPa",
    "taxels_above": "taxels above 0.5 kPa (mean over frames)",
    "peak_shear_p90": "90th-percentile peak shear magnitude, kPa",
    "shear_normal": "shear / normal (90th percentiles)",
    "contact": "frames in contact",
}
# The real recordings (10 participants, 335 performances): median, IQR, CV of participants.
REAL: dict[str, tuple[float, float, float, float | None]] = {
    "peak_normal_p90": (6.65, 2.88, 12.97, 0.22),
    "taxels_above": (5.57, 2.68, 9.45, 0.35),
    "peak_shear_p90": (0.72, 0.27, 1.27, 0.20),
    "shear_normal": (0.10, 0.08, 0.12, 0.06),
    "contact": (0.93, 0.88, 0.98, None),
}


def trial_stats(x: np.ndarray, channel_names: list[str]) -> dict[str, float]:
    """The statistics of one decoded trial ``(C, N, R, X)`` (see module doc)."""
    ch = {name: x[i] for i, name in enumerate(channel_names)}
    normal = ch.get("normal", ch.get("pressure"))
    n = normal.shape[0]
    flat = normal.reshape(n, -1)
    peak = flat.max(axis=1)
    above = flat > CONTACT_KPA
    out = {"peak_normal_p90": float(np.percentile(peak, 90)),
           "taxels_above": float(above.sum(axis=1).mean()),
           "contact": float(above.any(axis=1).mean())}
    if "shear_x" in ch:
        mag = np.hypot(ch["shear_x"], ch["shear_y"]).reshape(n, -1).max(axis=1)
        out["peak_shear_p90"] = float(np.percentile(mag, 90))
        out["shear_normal"] = out["peak_shear_p90"] / max(out["peak_normal_p90"], 1e-6)
    return out


def population_stats(trials: list[np.ndarray], participants: np.ndarray,
                     channel_names: list[str]) -> dict[str, dict[str, Any]]:
    """Per statistic: median, q25, q75 over trials and the CV of participants' medians."""
    rows = [trial_stats(t, channel_names) for t in trials]
    participants = np.asarray(participants)
    out: dict[str, dict[str, Any]] = {}
    for name in STAT_NAMES:
        if name not in rows[0]:
            continue
        v = np.array([r[name] for r in rows])
        meds = np.array([np.median(v[participants == p]) for p in np.unique(participants)])
        cv = float(meds.std() / meds.mean()) if len(meds) > 1 and meds.mean() > 0 else None
        q25, q50, q75 = np.percentile(v, [25, 50, 75])
        out[name] = {"median": float(q50), "q25": float(q25), "q75": float(q75), "cv": cv}
    return out


def pooled(populations: list[dict[str, dict[str, Any]]]) -> dict[str, dict[str, Any]]:
    """Several populations' statistics (each from :func:`population_stats`) as one: the
    mean of each figure, plus the lowest and highest CV. Ten people are a small sample
    (a CV of 10 medians moves by +-40% from one draw of ten to the next), so the
    simulator is judged on the mean over several populations of ten."""
    out: dict[str, dict[str, Any]] = {}
    for name in STAT_NAMES:
        have = [p[name] for p in populations if name in p]
        if not have:
            continue
        cvs = [h["cv"] for h in have if h.get("cv") is not None]
        out[name] = {k: float(np.mean([h[k] for h in have])) for k in ("median", "q25", "q75")}
        out[name].update(cv=float(np.mean(cvs)) if cvs else None,
                         cv_min=min(cvs) if cvs else None, cv_max=max(cvs) if cvs else None)
    return out


def ratios_to_real(stats: dict[str, dict[str, Any]]) -> dict[str, dict[str, float]]:
    """Per statistic, the simulator's median, IQR and between-person CV divided by the
    real recordings' (1.0 = the same; issue 37 asks for each within 0.75-1.25)."""
    out: dict[str, dict[str, float]] = {}
    for name, (med, q25, q75, cv) in REAL.items():
        s = stats.get(name)
        if not s or name == "contact":
            continue
        r = {"median": s["median"] / med, "iqr": (s["q75"] - s["q25"]) / (q75 - q25)}
        if cv is not None and s.get("cv") is not None:
            r["cv"] = s["cv"] / cv
        out[name] = r
    return out


def format_table(columns: dict[str, dict[str, dict[str, Any]]]) -> str:
    """A markdown table, one row per statistic and one column per population (``REAL``
    added first)."""
    def cell(s: dict[str, Any] | None, show_cv: bool) -> str:
        if not s:
            return "-"
        text = f"{s['median']:.2f} [{s['q25']:.2f}-{s['q75']:.2f}]"
        if show_cv and s.get("cv") is not None:
            text += f", CV {s['cv']:.2f}"
            if s.get("cv_min") is not None:
                text += f" ({s['cv_min']:.2f}-{s['cv_max']:.2f})"
        return text

    real = {k: {"median": m, "q25": a, "q75": b, "cv": cv} for k, (m, a, b, cv) in REAL.items()}
    cols = {"real": real, **columns}
    lines = ["| per trial | " + " | ".join(cols) + " |", "|---" * (len(cols) + 1) + "|"]
    for name in STAT_NAMES:
        show_cv = REAL[name][3] is not None
        lines.append(f"| {LABELS[name]} | " + " | ".join(cell(c.get(name), show_cv)
                                                       for c in cols.values()) + " |")
    return "\n".join(lines)
