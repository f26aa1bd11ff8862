"""HTML reports of wellness checks and calibrations, with figures embedded (one file)."""

from __future__ import annotations

import base64
import html
import io
import os
from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio.sensor.layout import SHEARSENSE_6X6, Layout
from tactile_studio.sensor.wellness import parse_taxel

_COLOURS = {"pass": "#2e8b57", "warn": "#d89a00", "fail": "#c0392b"}


def _png(fig: Any) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    import matplotlib.pyplot as plt
    plt.close(fig)
    return "<img src='data:image/png;base64," + base64.b64encode(buf.getvalue()).decode() + "'>"


def _figures_wellness(result: dict[str, Any], layout: Layout) -> list[str]:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figs = []
    fig, ax = plt.subplots(figsize=(4, 4))
    ax.set_xlim(-0.5, layout.cols - 0.5)
    ax.set_ylim(layout.rows - 0.5, -0.5)
    for r in range(layout.rows):
        for c in range(layout.cols):
            ax.add_patch(plt.Rectangle((c - 0.45, r - 0.45), 0.9, 0.9, color="#dddddd"))
            ax.text(c, r + 0.3, layout.taxel_name(r, c), ha="center", fontsize=7, color="#666")
    for s in result["spots"]:
        r, c = layout.taxel_rc(parse_taxel(layout, s["taxel"]))
        ax.add_patch(plt.Rectangle((c - 0.45, r - 0.45), 0.9, 0.9, color=_COLOURS[s["verdict"]]))
        ratio = "-" if s["ratio"] is None else f"{s['ratio'] * 100:.0f}%"
        ax.text(c, r, ratio, ha="center", va="center", color="white", fontsize=9)
    ax.set_title("spots: ratio to reference")
    ax.set_xticks([])
    ax.set_yticks([])
    figs.append(_png(fig))
    noise = np.asarray(result.get("noise") or [])
    if len(noise):
        fig, ax = plt.subplots(figsize=(7, 2.5))
        ax.bar(np.arange(len(noise)), noise, width=1.0, color="#4a6fa5")
        ax.set_xlabel("channel")
        ax.set_ylabel("noise (counts)")
        ax.set_title("rest noise per channel")
        figs.append(_png(fig))
    return figs


def _figures_calibration(cal: dict[str, Any]) -> list[str]:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fits = cal["fits"]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(9, 3.2))
    for f in fits:
        ax2.plot(f["loads_kpa"], f["residuals_kpa"], "o-", ms=3, lw=0.7, alpha=0.6)
    ax2.axhline(0, color="k", lw=0.5)
    ax2.set_xlabel("applied (kPa)")
    ax2.set_ylabel("residual (kPa)")
    ax2.set_title("residuals after calibration")
    ax1.bar(range(len(fits)), [f["rms_pct"] for f in fits], color="#4a6fa5")
    ax1.set_xticks(range(len(fits)), [f["taxel"] for f in fits], rotation=90, fontsize=6)
    ax1.set_ylabel("rms error (% of range)")
    ax1.set_title("per-taxel rms error")
    return [_png(fig)]


def write_report(path: str | os.PathLike, title: str, result: dict[str, Any],
                 kind: str = "wellness", layout: Layout = SHEARSENSE_6X6) -> Path:
    """Write a self-contained HTML page: verdict, reasons, tables and figures."""
    path = Path(path)
    esc = html.escape
    parts = [f"<html><head><meta charset='utf-8'><title>{esc(title)}</title>",
             "<style>body{font-family:sans-serif;margin:2em}td,th{padding:2px 8px}"
             "table{border-collapse:collapse}tr:nth-child(even){background:#f3f3f3}</style>"
             f"</head><body><h1>{esc(title)}</h1>"]
    if kind == "wellness":
        v = result["verdict"]
        parts.append(f"<h2 style='color:{_COLOURS[v]}'>{v.upper()}</h2><ul>"
                     + "".join(f"<li>{esc(r)}</li>" for r in result["reasons"]) + "</ul>")
        if result.get("tested"):  # a pass speaks only for the taxels loaded
            parts.append(f"<p>{esc(result['tested']['line'])}; ratios against "
                         f"{esc(result.get('judged_against') or 'the reference')}.</p>")
        parts.append("<table><tr><th>spot</th><th>normal kPa</th><th>&Delta;C/C0</th>"
                     "<th>shear kPa</th><th>ratio</th><th>verdict</th></tr>")
        for s in result["spots"]:
            ratio = "-" if s["ratio"] is None else f"{s['ratio']:.3f}"
            parts.append(f"<tr><td>{s['taxel']}</td><td>{s['normal_kpa']:.2f}</td>"
                         f"<td>{s['delta_c']:.4f}</td><td>{s['shear_kpa']:.2f}</td>"
                         f"<td>{ratio}</td><td>{s['verdict']}</td></tr>")
        parts.append("</table><p>channels: " + esc(str(result["channels"])) + "</p>")
        parts.append("<p>rest: " + esc(str(result["rest"])) + "</p>")
        parts.extend(_figures_wellness(result, layout))
    else:
        parts.append(f"<p>{esc(result['kind'])} calibration, loads "
                     f"{esc(str(result['loads_g']))} g; median rms "
                     f"{result['rms_pct_median']:.2f}% of range, worst "
                     f"{result['rms_pct_max']:.2f}%</p>")
        parts.extend(_figures_calibration(result))
    parts.append("</body></html>")
    path.write_text("\n".join(parts), encoding="utf-8")
    return path
