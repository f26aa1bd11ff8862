"""Figures like the paper's and an HTML report for a characterisation (matplotlib Agg).

Per taxel: sensor and load cell over time with the stage steps, the two-range normal
fit, the shear fits per direction, the relaxation fit and the neighbour responses.
For the array: heatmaps of sensitivity, R² and crosstalk (grey = not characterised).
"""

from __future__ import annotations

import html
from pathlib import Path
from typing import Any

import numpy as np

from tactile_studio.file_claims import replace_whole
from tactile_studio.sensor.characterise import exp_settle_fit, two_range_fit
from tactile_studio.sensor.layout import Layout

TABLE_KEYS = ("normal_sensitivity_low", "normal_sensitivity_high", "breakpoint_kpa",
              "shear_sensitivity_x", "shear_sensitivity_y", "r2_shear", "crosstalk_max",
              "relaxation_s", "hysteresis", "shear_offset", "repeat_drift", "settle_wait_s")
# what a lab notebook reads: (column title, unit, how the value is shown)
_PCT = "pct"
COLUMNS: dict[str, tuple[str, str, str]] = {
    "normal_sensitivity_low": ("Normal sensitivity, low range", "/kPa", "{:.4g}"),
    "normal_sensitivity_high": ("Normal sensitivity, high range", "/kPa", "{:.4g}"),
    "breakpoint_kpa": ("Breakpoint", "kPa", "{:.1f}"),
    "shear_sensitivity_x": ("Shear sensitivity x", "/kPa", "{:.4g}"),
    "shear_sensitivity_y": ("Shear sensitivity y", "/kPa", "{:.4g}"),
    "r2_shear": ("Shear fit R² (worst direction)", "", "{:.3f}"),
    "crosstalk_max": ("Normal crosstalk, worst neighbour", "%", _PCT),
    "settle_wait_s": ("Longest wait for a settled skin", "s", "{:.1f}"),
    "relaxation_s": ("Relaxation time constant", "s", "{:.2f}"),
    "hysteresis": ("Hysteresis", "% of loading area", _PCT),
    "shear_offset": ("Shear offset after release", "% of peak", _PCT),
    "repeat_drift": ("Peak drift over the repeats", "%", _PCT),
}
# maps: sensitivities against the array's median (the nominal value) within a tolerance,
# so a 3% spread looks like the 3% it is; R² and crosstalk on fixed, readable scales
TOLERANCE_PCT = 10.0
MAPS = (("normal_sensitivity_low", "Normal sensitivity, low range"),
        ("shear_sensitivity_x", "Shear sensitivity x"),
        ("r2_shear", "Shear fit R² (worst direction)"),
        ("crosstalk_max", "Normal crosstalk, worst neighbour"))


def column_title(key: str) -> str:
    """"Breakpoint (kPa)": a table header with its unit."""
    title, unit, _ = COLUMNS.get(key, (key.replace("_", " ").capitalize(), "", ""))
    return f"{title} ({unit})" if unit else title


def pct(fraction: float) -> str:
    """A fraction as a percentage with one decimal; never "-0.0%"."""
    v = round(float(fraction) * 100, 1)
    return f"{v + 0.0:.1f}%" if v != 0 else "0.0%"


def format_value(key: str, v: Any) -> str:
    """A table cell: "–" for missing or not measured, percentages for fractions."""
    if v is None or (isinstance(v, float) and not np.isfinite(v)):
        return "–"
    fmt = COLUMNS.get(key, ("", "", "{:.4g}"))[2]
    if fmt == _PCT:
        return pct(v)[:-1]  # the header carries the unit
    return fmt.format(v) if isinstance(v, (int, float)) else str(v)


def _figure(w: float, h: float, fig=None):  # noqa: ANN001, ANN202
    """A new figure, or ``fig`` (a subfigure of a taxel's page) when given."""
    if fig is not None:
        return fig
    from matplotlib.figure import Figure

    return Figure(figsize=(w, h), dpi=100, layout="constrained")


def _legend(ax) -> None:  # noqa: ANN001
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7)


def timeline_figure(name: str, raw: dict[str, Any], fig=None):  # noqa: ANN001, ANN201
    """Sensor (left axes) and load cell (right axes) at every stage step, in time:
    normal on top, shear below (each stage step is one stair)."""
    fig = _figure(9, 5.0, fig)
    top, bottom = fig.subplots(2, 1, sharex=True)
    pts = list(raw.get("normal", {}).get("points", []))
    for d in raw.get("shear", {}).get("directions", {}).values():
        pts += d["points"]
    pts = sorted(pts, key=lambda p: p["t"])
    t = np.array([p["t"] for p in pts])
    rows = ((top, (("normal", "tab:blue", "pz", "k", "normal"),), "normal"),
            (bottom, (("shear_x", "tab:green", "px", "r", "shear x"),
                      ("shear_y", "tab:olive", "py", "m", "shear y")), "shear"))
    for ax, series, label in rows:
        ax2 = ax.twinx()
        for key, colour, force_key, force_colour, what in series:
            ax.step(t, [p[key] for p in pts], where="post", color=colour,
                    label=f"sensor {what}")
            ax2.plot(t, [p[force_key] for p in pts], ".", color=force_colour, ms=3,
                     label=f"load cell {what}")
        ax.set_ylabel(f"sensor {label}\n(relative change)")
        ax2.set_ylabel("load cell (kPa)")
        h1, l1 = ax.get_legend_handles_labels()
        h2, l2 = ax2.get_legend_handles_labels()
        ax.legend(h1 + h2, l1 + l2, fontsize=7, ncols=2, loc="upper right")
    top.set_title(f"{name}: sensor and load cell at every stage step")
    bottom.set_xlabel("time (s, lab clock)")
    return fig


def fits_figure(name: str, raw: dict[str, Any], metrics: dict[str, Any],
                fig=None):  # noqa: ANN001, ANN201
    """Two-range normal fit, shear fits per direction, relaxation fit."""
    fig = _figure(11, 3.4, fig)
    a1, a2, a3 = fig.subplots(1, 3)
    if "normal" in raw:
        pts = raw["normal"]["points"]
        for phase, style in (("load", "o"), ("unload", "s")):
            sel = [p for p in pts if p["phase"] == phase]
            a1.plot([p["pz"] for p in sel], [p["normal"] for p in sel], style, mfc="none",
                    label=phase)
        both = [p for p in pts if p["phase"] in ("load", "unload")]
        fit = two_range_fit(np.array([p["pz"] for p in both]),
                            np.array([p["normal"] for p in both]))
        x = np.linspace(0, max(p["pz"] for p in pts), 100)
        a1.plot(x, fit.predict(x), "k-", lw=1,
                label=f"{fit.low:.4f} | {fit.high:.4f} /kPa, break {fit.breakpoint:.1f} kPa")
        a1.axvline(fit.breakpoint, color="grey", ls=":")
        t, y = np.asarray(raw["normal"]["relax_t"]), np.asarray(raw["normal"]["relax_y"])
        if len(t) > 10:
            tau, a, b = exp_settle_fit(t, y)
            a3.plot(t, y, ".", ms=2, label="sensor")
            a3.plot(t, a + b * np.exp(-(t - t.min()) / tau), "k-", lw=1,
                    label=f"fit τ = {tau:.2f} s")
    a1.set(xlabel="load cell normal stress (kPa)", ylabel="ΔC/C0 (centre)", title=f"{name}: normal")
    _legend(a1)
    for dname, d in raw.get("shear", {}).get("directions", {}).items():
        key, along = ("px", "shear_x") if "x" in dname else ("py", "shear_y")
        x = np.array([p[key] for p in d["points"]])
        y = np.array([p[along] for p in d["points"]])
        e = metrics.get("shear_by_direction", {}).get(dname, {})
        line, = a2.plot(x, y, "o", mfc="none", ms=4)
        if e.get("sensitivity") is not None:
            c = np.polyfit(x, y, 1)
            a2.plot(x, np.polyval(c, x), "-", color=line.get_color(), lw=1,
                    label=f"{dname}: {e['sensitivity']:.4f} /kPa, R² {e['r2']:.3f}")
    a2.set(xlabel="load cell shear stress (kPa)", ylabel="differential ΔC/C0", title="shear")
    _legend(a2)
    a3.set(xlabel="time at full depth (s)", ylabel="ΔC/C0", title="relaxation")
    _legend(a3)
    return fig


def neighbours_figure(layout: Layout, name: str, metrics: dict[str, Any],
                      fig=None):  # noqa: ANN001, ANN201
    """Normal and shear crosstalk to the 8 neighbours as 3x3 grids around the taxel."""
    fig = _figure(6.4, 3.0, fig)
    row = ord(name[0]) - ord("A")
    col = int(name[1:]) - 1
    for ax, key, title in zip(fig.subplots(1, 2), ("crosstalk_normal", "crosstalk_shear"),
                              ("normal crosstalk", "shear crosstalk")):
        grid = np.full((3, 3), np.nan)
        for n, v in (metrics.get(key) or {}).items():
            r, c = ord(n[0]) - ord("A") - row + 1, int(n[1:]) - 1 - col + 1
            grid[r, c] = v
        ax.imshow(grid, cmap="viridis", vmin=0, vmax=max(np.nanmax(grid), 1e-6)
                  if np.isfinite(grid).any() else 1)
        for (r, c), v in np.ndenumerate(grid):
            label = name if (r, c) == (1, 1) else (pct(v) if np.isfinite(v) else "")
            ax.text(c, r, label, ha="center", va="center", fontsize=8,
                    color="white" if (r, c) != (1, 1) else "black")
        ax.set_title(f"{name}: {title}", fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
    return fig


def _map_scale(key: str, grid: np.ndarray) -> tuple[np.ndarray, str, float, float, str, str]:
    """(values to colour, colour map, low, high, colour-bar label, cell text format) of
    one map: sensitivities as % from the array median within ±2x the tolerance, R² from
    0.9 to 1, crosstalk in % from 0."""
    finite = grid[np.isfinite(grid)]
    if key.endswith(("sensitivity_low", "sensitivity_x")):
        nominal = float(np.median(finite)) if finite.size else float("nan")
        dev = (grid / nominal - 1) * 100 if nominal else grid * np.nan
        span = 2 * TOLERANCE_PCT
        return (dev, "RdBu_r", -span, span,
                f"% from the median {nominal:.4g} /kPa (tolerance ±{TOLERANCE_PCT:g}%)",
                "{:+.1f}%")
    if key.startswith("r2"):
        return grid, "viridis", 0.9, 1.0, "R² (below 0.9 shown as 0.9)", "{:.3f}"
    top = max(10.0, float(np.ceil(finite.max() * 100)) if finite.size else 10.0)
    return grid * 100, "magma_r", 0.0, top, "% of the target's response", "{:.1f}%"


def _ink(cmap: str, t: float) -> str:
    """Black or white text, whichever reads on the cell's colour (``t``: 0..1 on the map)."""
    dark = {"RdBu_r": t < 0.2 or t > 0.8, "viridis": t < 0.55, "magma_r": t > 0.45}
    return "white" if dark.get(cmap, False) else "black"


def maps_figure(layout: Layout, taxels: dict[str, dict[str, Any]]):  # noqa: ANN201
    """Heatmaps on the array: sensitivity, R², crosstalk (grey: not characterised),
    each cell labelled with its value."""
    import matplotlib as mpl
    from matplotlib.ticker import FormatStrFormatter

    # two by two: beside a taxel's page in the wizard, and as tall as it is wide in the
    # report (a row of four was a strip a third as tall as the page was wide)
    fig = _figure(9.0, 7.6)
    cols = [layout.taxel_name(0, c)[1:] for c in range(layout.cols)]
    rows = [layout.taxel_name(r, 0)[:-1] for r in range(layout.rows)]
    grid_rows = (len(MAPS) + 1) // 2
    for ax, (key, title) in zip(fig.subplots(grid_rows, 2).ravel(), MAPS):
        grid = np.full((layout.rows, layout.cols), np.nan)
        for r in range(layout.rows):
            for c in range(layout.cols):
                v = taxels.get(layout.taxel_name(r, c), {}).get(key)
                grid[r, c] = np.nan if v is None else v
        shown, name, lo, hi, label, cell = _map_scale(key, grid)
        cmap = mpl.colormaps[name].with_extremes(bad="#cccccc")
        im = ax.imshow(np.ma.masked_invalid(shown), cmap=cmap, vmin=lo, vmax=hi)
        for (r, c), v in np.ndenumerate(shown):
            if np.isfinite(v):
                fmt = cell.replace(".1f", ".0f") if abs(v) >= 10 and "%" in cell else cell
                text = fmt.format(v + 0.0).replace("-0.0%", "0.0%").replace("+0.0%", "0.0%")
                ax.text(c, r, text, ha="center", va="center", fontsize=7,
                        color=_ink(name, float(np.clip((v - lo) / ((hi - lo) or 1), 0, 1))))
        ax.set_xticks(range(layout.cols), cols)
        ax.set_yticks(range(layout.rows), rows)
        ax.set_title(title, fontsize=9)
        bar = fig.colorbar(im, ax=ax, shrink=0.8)
        bar.set_label(label, fontsize=7)
        bar.ax.yaxis.set_major_formatter(FormatStrFormatter("%.2f" if key.startswith("r2")
                                                            else "%g"))
        bar.ax.yaxis.get_offset_text().set_visible(False)
    return fig


def taxel_figure(layout: Layout, name: str, raw: dict[str, Any],  # noqa: ANN201
                 metrics: dict[str, Any]):
    """One page per taxel: timeline, fits, neighbour responses (one render: fast)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11, 12), dpi=80)  # fixed margins: constrained layout doubles the cost
    top, mid, bottom = fig.subfigures(3, 1, height_ratios=(5, 3.6, 3))
    timeline_figure(name, raw, top)
    top.subplots_adjust(left=0.09, right=0.91, top=0.93, bottom=0.1, hspace=0.08)
    fits_figure(name, raw, metrics, mid)
    mid.subplots_adjust(left=0.07, right=0.98, top=0.9, bottom=0.15, wspace=0.3)
    if "crosstalk_normal" in metrics or "crosstalk_shear" in metrics:
        neighbours_figure(layout, name, metrics, bottom)
        bottom.subplots_adjust(left=0.15, right=0.85, top=0.9, bottom=0.04, wspace=0.2)
    return fig


def _when(stamp: Any) -> str:
    """"2026-01-01T09:30:00Z" -> "2026-01-01 09:30 UTC"."""
    text = str(stamp or "")
    return f"{text[:10]} {text[11:16]} UTC" if len(text) >= 16 and "T" in text else text or "–"


def _plugin(info: dict[str, Any]) -> str:
    """An instrument in words: its plugin and the settings that matter, not a dict."""
    settings = info.get("settings") or {}
    shown = ", ".join(f"{k} {v}" for k, v in settings.items() if not isinstance(v, dict))
    return html.escape(f"{info.get('plugin', '?')}" + (f" ({shown})" if shown else ""))


def write_report(out_dir: Path, result: dict[str, Any], layout: Layout,
                 raw: dict[str, Any]) -> list[Path]:
    """A page of figures per taxel and the array maps as PNGs under ``out_dir/figures``,
    plus ``out_dir/report.html``. ``raw``: the measured points per taxel."""
    out_dir = Path(out_dir)
    figdir = out_dir / "figures"
    figdir.mkdir(exist_ok=True)
    written: list[Path] = []

    def save(fig, name: str) -> str:  # noqa: ANN001
        path = figdir / name
        fig.savefig(path)
        written.append(path)
        return f"figures/{name}"

    taxels = result.get("taxels", {})
    maps = save(maps_figure(layout, taxels), "maps.png") if taxels else None
    sections = []
    for name, m in taxels.items():
        img = save(taxel_figure(layout, name, raw.get(name, {}), m), f"{name}.png")
        sections.append(f'<h2>{name}</h2><img src="{img}" alt="{name}">')
    head = "".join(f"<th>{html.escape(column_title(k))}</th>" for k in TABLE_KEYS)
    rows = "".join(f"<tr><td>{n}</td>" + "".join(
        f"<td>{html.escape(format_value(k, m.get(k)))}</td>" for k in TABLE_KEYS)
        + "</tr>" for n, m in taxels.items())
    status = ("complete" if result.get("complete")
              else f"INCOMPLETE: {html.escape(str(result.get('aborted')))}")
    page = f"""<!doctype html><html><head><meta charset="utf-8">
<title>Characterisation {html.escape(str(result.get('sensor') or ''))}</title>
<style>body{{font-family:sans-serif;margin:2em}} table{{border-collapse:collapse;font-size:12px}}
td,th{{border:1px solid #ccc;padding:3px 6px}} \
img{{max-width:100%;display:block;margin:1em 0}}</style>
</head><body>\
<h1>Characterisation of {html.escape(str(result.get('sensor') or result.get('layout')))}</h1>
<p>Run {status}: started {_when(result.get('started'))}, finished
{_when(result.get('finished'))}. Stage: {_plugin(result['stage'])}; load cell:
{_plugin(result['force'])}.</p>
<p>Sensitivities are the sensor's relative change (&Delta;C/C0; for shear the differential
change) per kPa measured by the load cell; a dash is a quantity the plan did not
measure.</p>
<table><tr><th>Taxel</th>{head}</tr>{rows}</table>
{f'<h2>Array maps</h2><img src="{maps}" alt="maps">' if maps else ''}
{''.join(sections)}</body></html>"""
    replace_whole(out_dir / "report.html", lambda tmp: tmp.write_text(page))
    written.append(out_dir / "report.html")
    return written
