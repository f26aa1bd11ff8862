"""Equilibration and calibration maths: known loads in, per-taxel curves out.

For every taxel the relative change of its centre channel (dC/C0) under known stresses
is fitted three ways, and the fit with the smallest leave-one-load-out error wins:

- ``linear``: kPa = a * r (through zero: the sensor is tared unloaded);
- ``two-range``: kPa = a * min(r, rb) + b * max(r - rb, 0), breakpoint ``rb`` fitted (the
  shear paper's normal response: steeper below ~9.3 kPa, shallower above);
- ``power``: kPa = a * r ** b (the Tekscan I-Scan model).

The rms error is reported as % of the calibrated range (the largest load). A taxel's
*sensitivity* is its response relative to the nominal curve of the layout (1 = nominal),
and *equilibration gains* are the factors that make every taxel read the same under a
uniform load. Applying a calibration never touches raw data: :func:`decode_calibrated`
turns raw frames into kPa with any calibration of the sensor.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.sensor.decode import StressFrames, decode, relative_change
from tactile_studio.sensor.layout import CENTRE, Layout

MODELS = ("linear", "two-range", "power")


class CalibrationError(UserError):
    """Unusable calibration input (loads out of order, too few, no response)."""


def check_loads(loads: list[float]) -> list[float]:
    """At least three positive loads in increasing order (as a person applies them)."""
    if len(loads) < 3:
        raise CalibrationError(f"calibration needs at least 3 loads, got {len(loads)}")
    if any(not math.isfinite(v) for v in loads):  # nan passes every comparison below
        raise CalibrationError("loads must be finite numbers: "
                               f"{', '.join(f'{v:g}' for v in loads)}")
    if any(v <= 0 for v in loads):
        raise CalibrationError(f"loads must be positive: {', '.join(f'{v:g}' for v in loads)}")
    for a, b in zip(loads, loads[1:]):
        if b <= a:
            raise CalibrationError(f"loads out of order: {b:g} after {a:g} (give them in "
                                   "increasing order)")
    return list(loads)


def _predict(model: str, p: tuple[float, ...], r: np.ndarray) -> np.ndarray:
    r = np.asarray(r, dtype=np.float64)
    if model == "linear":
        return p[0] * r
    if model == "two-range":
        a, b, rb = p
        return a * np.minimum(r, rb) + b * np.maximum(r - rb, 0.0)
    a, b = p
    return a * np.power(np.maximum(r, 1e-12), b)


def _fit(model: str, r: np.ndarray, kpa: np.ndarray) -> tuple[float, ...]:
    if model == "linear":
        return (float(r @ kpa / max(r @ r, 1e-18)),)
    if model == "power":
        keep = r > 0
        if keep.sum() < 2:
            raise np.linalg.LinAlgError("power law needs two positive responses")
        b, log_a = np.polyfit(np.log(r[keep]), np.log(kpa[keep]), 1)
        return (float(np.exp(log_a)), float(b))
    best: tuple[float, tuple[float, ...]] | None = None
    lo, hi = float(r.min()), float(r.max())
    # a faint pull of the two slopes towards each other settles folds the data leave
    # undetermined (no point beyond the break) on the straight line, not on a wild slope
    ridge = 1e-4 * float(np.sqrt(np.mean(kpa ** 2))) / max(hi, 1e-12)
    for rb in np.linspace(lo, hi, 101)[1:-1]:  # a break strictly inside the data
        basis = np.stack([np.minimum(r, rb), np.maximum(r - rb, 0.0)], axis=1)
        coef, *_ = np.linalg.lstsq(np.vstack([basis, [ridge * hi, -ridge * hi]]),
                                   np.append(kpa, 0.0), rcond=None)
        err = float(np.sum((basis @ coef - kpa) ** 2) + (ridge * hi * (coef[0] - coef[1])) ** 2)
        if best is None or err < best[0]:
            best = (err, (float(coef[0]), float(coef[1]), float(rb)))
    if best is None:
        raise np.linalg.LinAlgError("no breakpoint inside the data")
    return best[1]


def _cv_rms(model: str, samples: list[np.ndarray], kpa: np.ndarray, folds: int = 5) -> float:
    """k-fold cross-validated rms error over the recorded frames of every load.

    Frame i of each load belongs to fold ``i % folds``; each fold's model is fitted to
    the per-load means of the other folds and judged on the fold's own frames. (With only
    a handful of loads, leaving whole loads out would mostly test extrapolation.)
    Returns inf if the model cannot be fitted.
    """
    sq, n = 0.0, 0
    for f in range(folds):
        train = np.array([np.delete(x, np.s_[f::folds]).mean() if len(x) > folds else x.mean()
                          for x in samples])
        try:
            p = _fit(model, train, kpa)
        except (np.linalg.LinAlgError, ValueError):
            return float("inf")
        for x, k in zip(samples, kpa):
            test = x[f::folds]
            sq += float(np.sum((_predict(model, p, test) - k) ** 2))
            n += len(test)
    return float(np.sqrt(sq / max(n, 1)))


@dataclass
class TaxelFit:
    taxel: int
    name: str
    model: str
    params: tuple[float, ...]
    cv_rms_kpa: dict[str, float]
    rms_pct: float  # the curve through the loads' means: 0 when it has a parameter a load
    sensitivity: float
    loads_kpa: list[float]
    responses: list[float]
    residuals_kpa: list[float]

    @property
    def cv_pct(self) -> float:
        """The chosen curve's cross-validated rms error over the recorded frames, % of the
        range: what a reading's error is, where ``rms_pct`` (the curve through the means)
        reads 0 for a three-parameter curve through three loads."""
        top = max(self.loads_kpa) if self.loads_kpa else 0.0
        return float(self.cv_rms_kpa[self.model] / top * 100.0) if top > 0 else 0.0

    def to_dict(self) -> dict[str, Any]:
        return {"taxel": self.name, "index": self.taxel, "model": self.model,
                "params": list(self.params), "cv_rms_kpa": self.cv_rms_kpa,
                "rms_pct": round(self.rms_pct, 4), "cv_pct": round(self.cv_pct, 4),
                "sensitivity": round(self.sensitivity, 5),
                "loads_kpa": self.loads_kpa, "responses": self.responses,
                "residuals_kpa": self.residuals_kpa}


def fit_taxel(layout: Layout, taxel: int, loads_kpa: np.ndarray,
              samples: list[np.ndarray]) -> TaxelFit:
    """Choose and fit the best model for one taxel: ``samples[j]`` are the per-frame
    dC/C0 of its centre channel under load j. Among models whose cross-validated error
    is within 2% of the best, the simplest wins (linear, then two-range, then power)."""
    kpa = np.asarray(loads_kpa, dtype=np.float64)
    samples = [np.atleast_1d(np.asarray(x, dtype=np.float64)) for x in samples]
    r = np.array([x.mean() for x in samples])
    name = layout.taxel_name(*layout.taxel_rc(taxel))
    if np.any(r <= 0) or np.any(np.diff(r) <= 0):
        raise CalibrationError(f"{name}: the response does not grow with the load "
                               f"({', '.join(f'{v:.4f}' for v in r)}): dead or misplaced?")
    cv = {m: _cv_rms(m, samples, kpa) for m in MODELS}
    best = min(cv.values())
    model = next(m for m in MODELS if cv[m] <= best * 1.02)
    params = _fit(model, r, kpa)
    resid = _predict(model, params, r) - kpa
    rms_pct = float(np.sqrt(np.mean(resid ** 2)) / kpa.max() * 100.0)
    nominal = layout.calibration.normal_rel(kpa) if layout.calibration else kpa
    sensitivity = float(r @ nominal / (nominal @ nominal))  # heavy loads: least noise
    return TaxelFit(taxel, name, model, params, {m: round(v, 5) for m, v in cv.items()},
                    rms_pct, sensitivity, [round(float(v), 5) for v in kpa],
                    [round(float(v), 7) for v in r], [round(float(v), 5) for v in resid])


def equilibration_gains(sensitivity: dict[int, float]) -> dict[int, float]:
    """Per-taxel factors that equalise a uniform load (median taxel = 1)."""
    median = float(np.median(list(sensitivity.values())))
    return {t: median / s for t, s in sensitivity.items()}


def sensitivity_spread(sensitivities: list[float]) -> dict[str, Any]:
    """How much the taxels' sensitivities differ, measured: their relative standard
    deviation (std over median) and range. (A calibration used to carry only the
    simulated device's ``sensitivity_spread`` setting, 0.0 by default, beside
    sensitivities from 0.94 to 1.20.)"""
    v = np.asarray([x for x in sensitivities if x is not None and np.isfinite(x)], float)
    if not len(v):
        return {"sensitivity_spread": None, "sensitivity_range": None}
    return {"sensitivity_spread": round(float(v.std() / np.median(v)), 5),
            "sensitivity_range": [round(float(v.min()), 5), round(float(v.max()), 5)]}


def spread_line(cal: dict[str, Any]) -> str:
    """"sensitivity 0.941-1.198 across 36 taxels (spread 4.5%)" ("" without figures)."""
    lo_hi, spread = cal.get("sensitivity_range"), cal.get("sensitivity_spread")
    if not lo_hi or spread is None:
        return ""
    n = len([f for f in cal.get("fits", []) if f.get("from_calibration") is None])
    return (f"sensitivity {lo_hi[0]:.3f}-{lo_hi[1]:.3f} across {n} taxel"
            f"{'s' if n != 1 else ''} measured (spread {spread * 100:.1f}%, std over median)")


def calibration_data(layout: Layout, kind: str, loads_g: list[float], fits: list[TaxelFit],
                     extra: dict[str, Any] | None = None) -> dict[str, Any]:
    """The JSON form stored in the logbook and written to CAL.json."""
    sens = {f.taxel: f.sensitivity for f in fits}
    gains = equilibration_gains(sens)
    rms = [f.rms_pct for f in fits]
    cv = [f.cv_pct for f in fits]
    return {"format": "tactile-studio-calibration", "version": 1, "layout": layout.name,
            "kind": kind, "loads_g": list(loads_g), "fits": [f.to_dict() for f in fits],
            "gains": {f.name: round(gains[f.taxel], 5) for f in fits},
            "rms_pct_median": float(np.median(rms)), "rms_pct_max": float(np.max(rms)),
            "cv_pct_median": float(np.median(cv)), "cv_pct_max": float(np.max(cv)),
            **sensitivity_spread(list(sens.values())), **(extra or {})}


def decode_calibrated(layout: Layout, raw: np.ndarray, baseline: np.ndarray,
                      calibration: dict[str, Any]) -> StressFrames:
    """Decode raw frames to kPa with a stored calibration (raw data is not changed).

    Calibrated taxels use their own curve for normal stress and divide shear by their
    sensitivity; taxels the calibration does not cover keep the nominal curve.
    """
    if calibration.get("layout") not in (None, layout.name):
        raise UserError(f"calibration is for {calibration.get('layout')}, data is {layout.name}")
    out = decode(layout, raw, baseline)
    rel = relative_change(layout, raw, baseline)
    normal = out.normal.astype(np.float64)
    sx = None if out.shear_x is None else out.shear_x.astype(np.float64)
    sy = None if out.shear_y is None else out.shear_y.astype(np.float64)
    for f in calibration["fits"]:
        t = int(f["index"])
        r, c = layout.taxel_rc(t)
        normal[:, r, c] = _predict(f["model"], tuple(f["params"]),
                                   rel[:, layout.channel(t, CENTRE)])
        if sx is not None and sy is not None and f["sensitivity"] > 0:
            sx[:, r, c] /= f["sensitivity"]
            sy[:, r, c] /= f["sensitivity"]
    f32 = np.float32
    return StressFrames(normal.astype(f32), None if sx is None else sx.astype(f32),
                        None if sy is None else sy.astype(f32), out.units)


def expected_nominal_kpa(layout: Layout, fit: dict[str, Any], kpa: float) -> float:
    """What the nominal decode of a taxel reads under ``kpa`` according to its
    calibration: the wellness check's reference when the sensor has an active one."""
    model, params = fit["model"], tuple(fit["params"])
    lo, hi = 0.0, 1.0
    for _ in range(60):  # every model is increasing in r: bisection finds r for kpa
        mid = 0.5 * (lo + hi)
        if float(_predict(model, params, np.array([mid]))[0]) < kpa:
            lo = mid
        else:
            hi = mid
    r = 0.5 * (lo + hi)
    return float(layout.calibration.normal_kpa(np.array([r]))[0]) if layout.calibration else r


def coverage(layout_taxels: int, calibration: dict[str, Any]) -> dict[str, Any]:
    """What a calibration covers: ``taxels`` (how many have a curve), ``of`` (the array),
    ``measured`` (names measured by this calibration) and ``kept`` (calibration id ->
    names carried over from it when it merged with an earlier one)."""
    fits = calibration.get("fits", [])
    kept: dict[str, list[str]] = {}
    for f in fits:
        if f.get("from_calibration") is not None:
            kept.setdefault(str(f["from_calibration"]), []).append(f["taxel"])
    return {"taxels": len(fits), "of": layout_taxels,
            "measured": [f["taxel"] for f in fits if f.get("from_calibration") is None],
            "kept": kept}


def merge_calibration(new: dict[str, Any], old: dict[str, Any], old_id: int) -> dict[str, Any]:
    """``new`` merged over the sensor's active calibration ``old`` (id ``old_id``): the
    taxels ``new`` measured take its curves, the others keep ``old``'s (each kept fit says
    which calibration it came from), gains and rms summaries are over the merged set. A
    partial calibration (4 taxels) must not drop the other 32 back to the nominal curve.
    ``new`` unchanged when ``old`` is of another layout or covers nothing else."""
    if old.get("layout") != new.get("layout"):
        return new
    measured = {f["taxel"] for f in new["fits"]}
    kept = [{**f, "from_calibration": f.get("from_calibration", old_id)}
            for f in old.get("fits", []) if f["taxel"] not in measured]
    if not kept:
        return new
    fits = sorted([*new["fits"], *kept], key=lambda f: int(f["index"]))
    return {**new, **with_fits(fits), "merged": True, "merged_with": old_id}


def measured_only(calibration: dict[str, Any]) -> dict[str, Any]:
    """A merged calibration cut back to the taxels it measured itself (a replacement of
    the calibration it merged with: the others read with the nominal curve)."""
    fits = [f for f in calibration["fits"] if f.get("from_calibration") is None]
    return {**calibration, **with_fits(fits), "merged": False}


def with_fits(fits: list[dict[str, Any]]) -> dict[str, Any]:
    """``fits`` with the gains and rms summaries computed over them."""
    sens = {f["taxel"]: float(f["sensitivity"]) for f in fits if f["sensitivity"] > 0}
    median = float(np.median(list(sens.values()))) if sens else 1.0
    rms = [float(f["rms_pct"]) for f in fits] or [0.0]
    out = {"fits": fits, "gains": {t: round(median / s, 5) for t, s in sens.items()},
           "rms_pct_median": float(np.median(rms)), "rms_pct_max": float(np.max(rms))}
    cv = [float(f["cv_pct"]) for f in fits if "cv_pct" in f]  # none before it was kept
    if cv:
        out.update(cv_pct_median=float(np.median(cv)), cv_pct_max=float(np.max(cv)))
    return out
