"""Individual differences, as in the shear paper: how much of each touch metric is the
gesture, the person and the surface?

Per trial (decoded, physical grid) the gesture metrics of :mod:`features` (mean normal
stress, mean |shear|, contact area, dominant frequency, centroid speed) and the
population statistics of :mod:`touch_stats` (90th-percentile peaks, shear/normal). Each
metric is modelled with a Gaussian GLM (statsmodels) ``metric ~ gesture + participant
[+ surface]``; a factor's effect is what dropping it costs: deviance explained, partial
eta² = ΔD / (ΔD + D_full), and the F-test p-value. Each participant's shear/normal
balance is the median over their trials of mean |shear| / mean normal stress.

:func:`individual_report` writes ``trials.csv``, ``glm.csv``, ``balance.csv``, three
figures and ``index.html`` to a folder.
"""

from __future__ import annotations

import csv
import html
import os
from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.jobs import CancelToken, ProgressFn, no_progress
from tactile_studio.learn.data.dataset import build_dataset, find_session_files
from tactile_studio.learn.data.features import gesture_metrics
from tactile_studio.learn.data.touch_stats import trial_stats

METRICS = ("mean_normal", "mean_abs_shear", "contact_area", "dominant_hz", "centroid_speed",
           "peak_normal_p90", "peak_shear_p90", "shear_normal")
FACTORS = ("gesture", "participant", "surface")


def _surfaces(paths: list[str]) -> dict[str, str]:
    """Session path (relative, as in trial uids) -> its ``condition`` (the surface)."""
    from tactile_studio.storage.format.session_file import SessionFile

    files, root = find_session_files(paths)
    out = {}
    for f in files:
        with SessionFile(f) as s:
            rel = f.relative_to(root).as_posix() if root else f.name
            out[rel] = str(s.metadata.get("condition") or "unknown")
    return out


def trial_table(paths: list[str], cache_dir: str | None = None,
                progress: ProgressFn = no_progress,
                cancel: CancelToken | None = None) -> list[dict[str, Any]]:
    """One row per trial: uid, participant, gesture, surface and every metric."""
    ds = build_dataset(paths, "physical", None, cache_dir, True,
                       lambda f, m: progress(0.3 * f, m), cancel)
    surfaces = _surfaces(paths)
    rows = []
    for i, x in enumerate(ds.trials):
        if cancel is not None:
            cancel.check()
        if i % 50 == 0:
            progress(0.3 + 0.5 * i / len(ds), f"metrics of trial {i + 1}/{len(ds)}")
        g = gesture_metrics(x, ds.channel_names, float(ds.rates[i]))
        s = trial_stats(x, ds.channel_names)
        row = {"uid": ds.uids[i], "participant": str(ds.participants[i]),
               "gesture": ds.label_names[ds.labels[i]],
               "surface": surfaces.get(ds.uids[i].rsplit("#", 1)[0], "unknown")}
        row.update({m: float({**g, **s}.get(m, np.nan)) for m in METRICS})
        rows.append(row)
    return rows


def glm_effects(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per metric and factor: deviance explained, partial eta², p (see module doc)."""
    import pandas as pd
    import statsmodels.api as sm
    import statsmodels.formula.api as smf
    from scipy import stats

    df = pd.DataFrame(rows)
    factors = [f for f in FACTORS if df[f].nunique() > 1]
    out = []
    for metric in METRICS:
        d = df[np.isfinite(df[metric])]
        if len(d) < 3 or d[metric].std() == 0 or not factors:
            continue
        formula = lambda fs: f"{metric} ~ " + (" + ".join(f"C({f})" for f in fs)  # noqa: E731
                                               or "1")
        full = smf.glm(formula(factors), d, family=sm.families.Gaussian()).fit()
        for f in factors:
            reduced = smf.glm(formula([g for g in factors if g != f]), d,
                              family=sm.families.Gaussian()).fit()
            dd = max(reduced.deviance - full.deviance, 0.0)
            ddf = max(int(round(reduced.df_resid - full.df_resid)), 1)
            fstat = (dd / ddf) / (full.deviance / full.df_resid) if full.df_resid > 0 else np.nan
            p = float(stats.f.sf(fstat, ddf, full.df_resid)) if np.isfinite(fstat) else np.nan
            out.append({"metric": metric, "factor": f, "df": ddf,
                        "deviance_explained": dd / max(full.null_deviance, 1e-12),
                        "partial_eta2": dd / max(dd + full.deviance, 1e-12), "p": p,
                        "n": int(len(d))})
    return out


def shear_balance(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per participant: median [IQR] of mean |shear| / mean normal over their trials."""
    out = []
    for p in sorted({r["participant"] for r in rows}):
        v = np.array([r["mean_abs_shear"] / r["mean_normal"] for r in rows
                      if r["participant"] == p and r["mean_normal"] > 0
                      and np.isfinite(r["mean_abs_shear"])])
        if len(v):
            q25, q50, q75 = np.percentile(v, [25, 50, 75])
            out.append({"participant": p, "median": float(q50), "q25": float(q25),
                        "q75": float(q75), "trials": int(len(v))})
    return out


def _write_csv(path: Path, rows: list[dict[str, Any]]) -> None:
    with open(path, "w", newline="") as fh:
        if rows:
            w = csv.DictWriter(fh, list(rows[0]))
            w.writeheader()
            w.writerows(rows)


def individual_report(paths: list[str], out: str | os.PathLike, cache_dir: str | None = None,
                      progress: ProgressFn = no_progress,
                      cancel: CancelToken | None = None) -> dict[str, Any]:
    """Write the individual-differences report to ``out``; returns its numbers."""
    from tactile_studio.learn.evaluation import individual_plots as plots

    out = Path(out)
    rows = trial_table(paths, cache_dir, progress, cancel)
    if len({r["participant"] for r in rows}) < 2:
        raise UserError("the individual-differences report needs at least 2 participants")
    progress(0.8, "fitting GLMs")
    effects = glm_effects(rows)
    balance = shear_balance(rows)
    out.mkdir(parents=True, exist_ok=True)
    _write_csv(out / "trials.csv", rows)
    _write_csv(out / "glm.csv", effects)
    _write_csv(out / "balance.csv", balance)
    progress(0.9, "drawing figures")
    figures = {"effects.png": plots.effects_png(out / "effects.png", effects),
               "balance.png": plots.balance_png(out / "balance.png", balance),
               "metrics.png": plots.metrics_png(out / "metrics.png", rows)}
    _write_html(out / "index.html", rows, effects, balance, figures)
    progress(1.0, f"report in {out}")
    return {"trials": len(rows), "effects": effects, "balance": balance}


def _write_html(path: Path, rows, effects, balance, figures) -> None:
    e = html.escape
    people = sorted({r["participant"] for r in rows})
    gestures = sorted({r["gesture"] for r in rows})
    surfaces = sorted({r["surface"] for r in rows})
    parts = ["<!doctype html><html><head><meta charset='utf-8'><title>Individual "
             "differences</title><style>body{font-family:sans-serif;max-width:1000px;"
             "margin:2em auto}table{border-collapse:collapse}td,th{border:1px solid #ccc;"
             "padding:3px 8px;text-align:right}</style></head><body>",
             "<h1>Individual differences</h1>",
             f"<p>{len(rows)} trials, {len(people)} participants, {len(gestures)} gestures, "
             f"surfaces: {e(', '.join(surfaces))}. Gaussian GLM per metric: "
             "<code>metric ~ gesture + participant [+ surface]</code>; effect of a factor = "
             "what dropping it costs (partial &eta;&sup2; = &Delta;D / (&Delta;D + D), "
             "F-test).</p>"]
    for name in figures:
        parts.append(f"<p><img src='{e(name)}' style='max-width:100%'></p>")
    parts.append("<h2>Effects</h2><table><tr><th>metric</th><th>factor</th><th>df</th>"
                 "<th>deviance explained</th><th>partial &eta;&sup2;</th><th>p</th></tr>")
    for r in effects:
        parts.append(f"<tr><td>{e(r['metric'])}</td><td>{e(r['factor'])}</td><td>{r['df']}"
                     f"</td><td>{r['deviance_explained']:.3f}</td><td>{r['partial_eta2']:.3f}"
                     f"</td><td>{r['p']:.2g}</td></tr>")
    parts.append("</table><h2>Shear / normal balance per participant</h2><table><tr>"
                 "<th>participant</th><th>median</th><th>IQR</th><th>trials</th></tr>")
    for b in balance:
        parts.append(f"<tr><td>{e(b['participant'])}</td><td>{b['median']:.3f}</td>"
                     f"<td>{b['q25']:.3f}-{b['q75']:.3f}</td><td>{b['trials']}</td></tr>")
    parts.append("</table><p>Per-trial values: trials.csv; effects: glm.csv; balance: "
                 "balance.csv.</p></body></html>")
    path.write_text("\n".join(parts), encoding="utf-8")
