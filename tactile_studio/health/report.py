"""HTML reports of wellness checks and calibrations, with figures embedded (one file)."""

from __future__ import annotations

import base64
import html
import io
import os
from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio.file_claims import written_whole
from tactile_studio.sensor.calibration import spread_line
from tactile_studio.sensor.layout import SHEARSENSE_6X6, Layout
from tactile_studio.sensor.wellness import channel_label, parse_taxel

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
    fig, ax = plt.subplots(figsize=(4.6, 4.6))
    ax.set_xlim(-0.5, layout.cols - 0.5)
    ax.set_ylim(layout.rows - 0.5, -0.5)
    for r in range(layout.rows):
        for c in range(layout.cols):
            ax.add_patch(plt.Rectangle((c - 0.45, r - 0.45), 0.9, 0.9, color="#e4e4e4"))
    for s in result["spots"]:
        r, c = layout.taxel_rc(parse_taxel(layout, s["taxel"]))
        ax.add_patch(plt.Rectangle((c - 0.45, r - 0.45), 0.9, 0.9, color=_COLOURS[s["verdict"]]))
        ratio = "-" if s["ratio"] is None else f"{s['ratio'] * 100:.0f}%"
        ax.text(c, r, f"{s['taxel']}\n{ratio}", ha="center", va="center", color="white",
                fontsize=9, fontweight="bold")
    ax.set_title("loaded spots: sensitivity vs reference")
    # taxel names on the axes, readable at any size (rows A.., columns 1..)
    ax.set_xticks(range(layout.cols), [str(c + 1) for c in range(layout.cols)])
    ax.set_yticks(range(layout.rows), [layout.taxel_name(r, 0)[:-1] for r in range(layout.rows)])
    ax.tick_params(length=0, labelsize=10)
    ax.xaxis.tick_top()
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
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(9, 3.2), layout="constrained")
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


_CHANNEL_KINDS = (("dead", "Dead (no baseline)"), ("stuck", "Stuck (never moves)"),
                  ("noisy", "Noisy (3x the median noise)"),
                  ("saturated", "Saturated (at the rail)"))
_REST_ROWS = (("frames", "Frames at rest", "{:d}"),
              ("noise_counts_median", "Noise, median channel (counts)", "{:.2f}"),
              ("noise_counts_max", "Noise, worst channel (counts)", "{:.2f}"),
              ("drift_pct_per_min_max", "Baseline drift, worst channel (% per min)", "{:.3f}"),
              ("baseline_shift_pct_max", "Baseline shift vs reference, worst channel (%)",
               "{:.2f}"))


def _channels_html(channels: dict[str, Any], layout: Layout) -> str:
    """Channel problems in words, each channel by its taxel ("E5/centre")."""
    rows = "".join(
        f"<tr><td>{title}</td><td>"
        + (html.escape(", ".join(channel_label(layout, int(c)) for c in channels.get(key) or ()))
           or "none") + "</td></tr>"
        for key, title in _CHANNEL_KINDS)
    return f"<h3>Channels</h3><table>{rows}</table>"


def _rest_html(rest: dict[str, Any]) -> str:
    """The rest phase as a labelled table with units (no raw keys)."""
    rows = "".join(
        f"<tr><td>{title}</td><td>{'-' if rest.get(key) is None else fmt.format(rest[key])}"
        "</td></tr>" for key, title, fmt in _REST_ROWS if key in rest)
    return f"<h3>At rest</h3><table>{rows}</table>"


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
        parts.append("<table><tr><th>Spot</th><th>Normal stress read (kPa)</th>"
                     "<th>Centre response &Delta;C/C0</th><th>Shear read (kPa)</th>"
                     "<th>Sensitivity vs reference</th><th>Verdict</th></tr>")
        for s in result["spots"]:
            ratio = "-" if s["ratio"] is None else f"{s['ratio'] * 100:.0f}%"
            parts.append(f"<tr><td>{s['taxel']}</td><td>{s['normal_kpa']:.2f}</td>"
                         f"<td>{s['delta_c']:.4f}</td><td>{s['shear_kpa']:.2f}</td>"
                         f"<td>{ratio}</td><td>{s['verdict']}</td></tr>")
        parts.append("</table>")
        parts.append(_channels_html(result.get("channels") or {}, layout))
        parts.append(_rest_html(result.get("rest") or {}))
        parts.extend(_figures_wellness(result, layout))
    else:
        loads = ", ".join(f"{g:g}" for g in result.get("loads_g") or ())
        parts.append(f"<p>{esc(result['kind'])} calibration, loads "
                     f"{esc(loads)} g; median rms "
                     f"{result['rms_pct_median']:.2f}% of range, worst "
                     f"{result['rms_pct_max']:.2f}%</p>")
        if spread_line(result):
            parts.append(f"<p>{esc(spread_line(result))}</p>")
        parts.extend(_figures_calibration(result))
    parts.append("</body></html>")
    page = "\n".join(parts)
    # whole or not at all (a cut report of a stored check would pass for the whole one),
    # one writer at a time
    written_whole(path, lambda tmp: tmp.write_text(page, encoding="utf-8"), what="report")
    return path
