"""Per-taxel metrics from the collected sequences (the numbers of characterisation.json)."""

from __future__ import annotations

from typing import Any

import numpy as np

from tactile_studio.sensor.characterise import (
    drift,
    exp_settle_fit,
    hysteresis,
    linear_fit,
    two_range_fit,
)

_SHEAR_AXIS = {"+x": ("px", "shear_x", "shear_y"), "-x": ("px", "shear_x", "shear_y"),
               "+y": ("py", "shear_y", "shear_x"), "-y": ("py", "shear_y", "shear_x")}


def _nan_to_none(d: dict[str, Any]) -> dict[str, Any]:
    def fix(v: Any) -> Any:
        if isinstance(v, dict):
            return _nan_to_none(v)
        if isinstance(v, float) and not np.isfinite(v):
            return None
        return v
    return {k: fix(v) for k, v in d.items()}


def baseline_drift(t: Any, tare_t: float | None, zero_t: float | None,
                   zero: float) -> np.ndarray:
    """The baseline's drift at times ``t``: the sensor read zero at the tare (``tare_t``)
    and ``zero`` on the settled, unloaded skin at ``zero_t``; linear between (the
    sensor's wander is minutes long, a staircase or a run of cycles under two). Zeros
    for an older run that did not record both."""
    t = np.asarray(t, float)
    if tare_t is None or zero_t is None or zero_t <= tare_t:
        return np.zeros_like(t)
    return (t - tare_t) / (zero_t - tare_t) * zero


def drift_corrected(data: dict[str, Any]) -> list[dict[str, Any]]:
    """The staircase's points less the baseline's drift over it (its zero after: the
    "lifted" point, read on a settled skin)."""
    pts = data["points"]
    lifted = [p for p in pts if p["phase"] == "lifted"]
    if not lifted:
        return pts
    end = lifted[0]
    out = []
    for p in pts:
        if p["phase"] in ("load", "unload"):
            p = {**p, "normal": p["normal"] - float(baseline_drift(
                p["t"], data.get("tare_t"), end["t"], end["normal"]))}
        out.append(p)
    return out


def analyse_normal(data: dict[str, Any]) -> dict[str, Any]:
    pts = drift_corrected(data)
    load = [p for p in pts if p["phase"] == "load"]
    unload = [p for p in pts if p["phase"] == "unload"]
    p_l = np.array([p["pz"] for p in load])
    y_l = np.array([p["normal"] for p in load])
    # loading and unloading together: the viscoelastic lag shifts them in opposite
    # directions, so fitting both cancels it to first order
    both = load + unload
    fit = two_range_fit(np.array([p["pz"] for p in both]), np.array([p["normal"] for p in both]))
    # crosstalk at full depth once relaxed, against the reading just before that press
    # (a local zero: baseline drift over the staircase would swamp a neighbour's few %)
    relaxed = [p for p in pts if p["phase"] == "relaxed"]
    lifted = [p for p in pts if p["phase"] == "lifted"]
    top, zero = (relaxed[-1], lifted[-1]) if relaxed and lifted else (load[-1], load[0])
    gain = top["normal"] - zero["normal"]
    ratios = {n: (v - zero["nb_normal"][n]) / gain for n, v in top["nb_normal"].items()} \
        if gain else {}
    # the calibration this fit gives (stress from the reading, through the origin) and
    # its rms error over every point, as % of the stress range
    p_all = np.array([p["pz"] for p in both])
    y_all = np.array([p["normal"] for p in both])
    y_break = fit.low * fit.breakpoint
    back = np.where(y_all <= y_break, y_all / fit.low,
                    fit.breakpoint + (y_all - y_break) / fit.high)
    span = float(p_all.max() - p_all.min()) or 1.0
    out: dict[str, Any] = {
        "normal_sensitivity_low": fit.low, "normal_sensitivity_high": fit.high,
        "breakpoint_kpa": fit.breakpoint, "r2_normal": fit.r2,
        "calibration_rms_pct": float(np.sqrt(np.mean((back - p_all) ** 2)) / span * 100),
        "max_normal_kpa": float(p_l.max()),
        "hysteresis": hysteresis(p_l, y_l, np.array([p["pz"] for p in unload]),
                                 np.array([p["normal"] for p in unload])),
        "crosstalk_normal": ratios,
        "crosstalk_max": max(ratios.values()) if ratios else float("nan"),
        # decoupling: shear read under pure normal load, per unit of normal response
        "shear_under_normal": float(max(abs(top["shear_x"]), abs(top["shear_y"]))
                                    / abs(top["normal"])) if top["normal"] else float("nan"),
    }
    t, y = np.asarray(data["relax_t"]), np.asarray(data["relax_y"])
    if len(t) > 10:
        out["relaxation_s"] = exp_settle_fit(t, y)[0]
    return out


def analyse_shear(data: dict[str, Any], tau: float | None) -> dict[str, Any]:
    by_dir: dict[str, Any] = {}
    offsets, cross_shear = [], {}
    for name, d in data["directions"].items():
        stress_key, along, across = _SHEAR_AXIS[name]
        pts = d["points"]
        x = np.array([p[stress_key] for p in pts])
        y = np.array([p[along] for p in pts])
        fit = linear_fit(x, y)
        peak = pts[-1][along] - pts[0][along]
        entry = {"sensitivity": fit.slope, "r2": fit.r2,
                 "cross_axis": (pts[-1][across] - pts[0][across]) / peak if peak else None,
                 "normal_under_shear": (pts[-1]["normal"] - pts[0]["normal"]) / peak
                 if peak else None}
        t, ry = np.asarray(d["return_t"]), np.asarray(d["return_y"])
        if len(t) > 5 and peak:
            # both ends settle with the relaxation time; their asymptotes a few seconds
            # apart give the offset free of the baseline drift over the whole drag
            _, asym, _ = exp_settle_fit(t, ry, tau)
            lt, ly = np.asarray(d.get("lifted_t", [])), np.asarray(d.get("lifted_y", []))
            zero = exp_settle_fit(lt, ly, tau)[1] if len(lt) > 5 else pts[0][along]
            entry["offset"] = (asym - zero) / peak
            offsets.append(entry["offset"])
        by_dir[name] = entry
        top = pts[-1]
        for n in top["nb_" + along]:
            r = (top["nb_" + along][n] - pts[0]["nb_" + along][n]) / peak if peak else np.nan
            cross_shear[n] = max(cross_shear.get(n, 0.0), abs(r))

    def mean_of(names: tuple[str, ...]) -> float:
        v = [by_dir[n]["sensitivity"] for n in names if n in by_dir]
        return float(np.mean(v)) if v else float("nan")

    r2 = [e["r2"] for e in by_dir.values()]
    return {"shear_sensitivity_x": mean_of(("+x", "-x")),
            "shear_sensitivity_y": mean_of(("+y", "-y")),
            "r2_shear": float(min(r2)) if r2 else float("nan"),
            "shear_offset": float(np.mean(offsets)) if offsets else float("nan"),
            "shear_by_direction": by_dir, "crosstalk_shear": cross_shear,
            "crosstalk_shear_max": max(cross_shear.values()) if cross_shear else float("nan")}


def analyse_repeat(data: dict[str, Any]) -> dict[str, Any]:
    peaks = np.asarray(data["peaks"], float)
    if "t" in data:
        peaks = peaks - baseline_drift(data["t"], data.get("tare_t"), data.get("zero_t"),
                                       data.get("zero", 0.0))
    d, cv = drift(peaks)
    return {"repeat_cycles": len(data["peaks"]), "repeat_drift": d, "repeat_cv": cv}


def analyse_taxel(data: dict[str, Any]) -> dict[str, Any]:
    """Every metric the collected sequences allow (a missing sequence leaves its out)."""
    out: dict[str, Any] = {}
    if "normal" in data:
        out.update(analyse_normal(data["normal"]))
    if "shear" in data:
        out.update(analyse_shear(data["shear"], out.get("relaxation_s")))
    if "repeat" in data:
        out.update(analyse_repeat(data["repeat"]))
    return _nan_to_none(out)
