"""The paper's sequences on one taxel: normal staircase, relaxation, shear drags, cycles.

Each returns plain data (lists of dicts, traces) for :mod:`.analyse`; every measured
point is also journaled into the session as a ``char_point`` event.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from tactile_studio.characterise.lab import Lab, Reading
from tactile_studio.characterise.plan import Plan
from tactile_studio.instruments.contract import InstrumentError
from tactile_studio.jobs import ProgressFn
from tactile_studio.sensor.characterise import neighbours

_AXIS = {"+x": (0, 1.0), "-x": (0, -1.0), "+y": (1, 1.0), "-y": (1, -1.0)}


def _point(lab: Lab, taxel: int, r: Reading, **extra: Any) -> dict[str, Any]:
    nb = neighbours(lab.layout, taxel)
    p = {**extra, "t": round(r.t1, 4), "fx": r.force_n[0], "fy": r.force_n[1], "fz": r.force_n[2],
         "px": r.stress_kpa[0], "py": r.stress_kpa[1], "pz": r.stress_kpa[2],
         "normal": r.normal[taxel], "shear_x": r.shear_x[taxel], "shear_y": r.shear_y[taxel],
         "nb_normal": {n: float(r.normal[t]) for n, t in nb.items()},
         "nb_shear_x": {n: float(r.shear_x[t]) for n, t in nb.items()},
         "nb_shear_y": {n: float(r.shear_y[t]) for n, t in nb.items()}}
    p = {k: (float(v) if isinstance(v, np.floating) else v) for k, v in p.items()}
    name = lab.layout.taxel_name(*lab.layout.taxel_rc(taxel))
    lab.event("char_point", taxel=name, **{k: v for k, v in p.items() if not k.startswith("nb_")})
    if lab.on_point is not None:
        lab.on_point(name, p)
    return p


def lift_and_tare(lab: Lab, plan: Plan, taxel: int, x0: float, y0: float,
                  z_above: float) -> None:
    """Lift over the taxel, wait for a settled skin (at least ``settle_s``), then tare:
    each sequence starts from the same state whatever came before it."""
    lab.move(x0, y0, z_above, plan.travel_speed_mm_s, plan.acceleration_mm_s2)
    lab.wait_steady(taxel, plan.settle_s, plan.settle_max_s, plan.steady_per_s)
    lab.tare(min(1.0, plan.settle_s))


def find_load(lab: Lab, plan: Plan, z_start: float, kpa: float) -> float:
    """Step down from ``z_start`` until the load cell reads ``kpa``; returns that z."""
    z = z_start
    limit = z_start - plan.approach_mm - plan.normal_depth_mm - 0.5
    while z > limit:
        z = round(z - plan.search_step_mm, 6)
        lab.move(z=z, speed=plan.speed_mm_s, acceleration=plan.acceleration_mm_s2)
        r = lab.hold(0.1, 0.05)
        if r.stress_kpa[2] >= kpa:
            return z
    raise InstrumentError(f"stage {lab.stage.name}: no {kpa} kPa on the load cell down to "
                          f"z={limit:.2f} mm (indenter over the sensor? load cell connected?)")


def normal_sequence(lab: Lab, plan: Plan, taxel: int, x0: float, y0: float) -> dict[str, Any]:
    """Staircase 0 -> depth -> 0 (loading, unloading), then one step held for relaxation."""
    lift_and_tare(lab, plan, taxel, x0, y0, plan.approach_mm)
    t_tare = lab.clock.now()
    z_surface = find_load(lab, plan, plan.approach_mm, plan.contact_kpa) + plan.search_step_mm
    lab.move(z=z_surface, speed=plan.speed_mm_s)
    depths = np.linspace(0.0, plan.normal_depth_mm, plan.normal_steps + 1)
    points = []
    for phase, seq in (("load", depths), ("unload", depths[-2::-1])):
        for d in seq:
            lab.move(z=z_surface - d, speed=plan.speed_mm_s, acceleration=plan.acceleration_mm_s2)
            r = lab.hold(plan.dwell_s, plan.window_s)
            points.append(_point(lab, taxel, r, sequence="normal", phase=phase, depth_mm=float(d)))
    lab.move(z=z_surface + plan.approach_mm, speed=plan.speed_mm_s)
    # lifted on a settled skin: the zero at the staircase's end, against the tare at its
    # start (the baseline's drift over it), and the local zero of the crosstalk ratios
    lab.wait_steady(taxel, plan.settle_s, plan.settle_max_s, plan.steady_per_s)
    pre = lab.read_window(lab.clock.now() - plan.window_s, lab.clock.now())
    points.append(_point(lab, taxel, pre, sequence="normal", phase="lifted", depth_mm=0.0))
    lab.move(z=z_surface - plan.normal_depth_mm, speed=plan.speed_mm_s,
             acceleration=plan.acceleration_mm_s2)
    t_start = lab.clock.now()
    lab.clock.sleep(plan.relax_hold_s, lab.cancel)
    t, normal, _, _ = lab.signals(t_start, lab.clock.now())
    end = lab.read_window(lab.clock.now() - plan.window_s, lab.clock.now())
    points.append(_point(lab, taxel, end, sequence="normal", phase="relaxed",
                         depth_mm=plan.normal_depth_mm))
    lab.move(z=z_surface + plan.approach_mm, speed=plan.speed_mm_s)
    return {"points": points, "z_surface": z_surface, "tare_t": round(t_tare, 4),
            "relax_t": (t - t_start).tolist(), "relax_y": normal[:, taxel].tolist()}


def shear_sequence(lab: Lab, plan: Plan, taxel: int, x0: float, y0: float) -> dict[str, Any]:
    """Per direction: preload, drag out in steps, return, hold (the offset), lift."""
    out: dict[str, Any] = {"directions": {}}
    z_pre: float | None = None
    n = int(round(plan.shear_max_mm / plan.shear_step_mm))
    for name in plan.directions:
        axis, sign = _AXIS[name]
        lift_and_tare(lab, plan, taxel, x0, y0, plan.approach_mm)
        if z_pre is None:
            z_pre = find_load(lab, plan, plan.approach_mm, plan.preload_kpa)
        else:
            lab.move(z=z_pre, speed=plan.speed_mm_s)
        points = []
        for k in range(n + 1):
            d = sign * k * plan.shear_step_mm
            lab.move(x0 + (d if axis == 0 else 0.0), y0 + (d if axis == 1 else 0.0),
                     speed=plan.speed_mm_s, acceleration=plan.acceleration_mm_s2)
            r = lab.hold(plan.dwell_s, plan.window_s)
            points.append(_point(lab, taxel, r, sequence="shear", direction=name,
                                 displacement_mm=float(d)))
        lab.move(x0, y0, speed=plan.speed_mm_s, acceleration=plan.acceleration_mm_s2)
        t_start = lab.clock.now()
        lab.clock.sleep(plan.return_dwell_s, lab.cancel)
        t, _, sx, sy = lab.signals(t_start, lab.clock.now())
        trace = (sx if axis == 0 else sy)[:, taxel]
        lab.move(z=plan.approach_mm, speed=plan.speed_mm_s)
        t_lift = lab.clock.now()  # lifted: the local zero the offset is measured from
        lab.clock.sleep(plan.settle_s, lab.cancel)
        lt, _, lsx, lsy = lab.signals(t_lift, lab.clock.now())
        out["directions"][name] = {"points": points, "return_t": (t - t_start).tolist(),
                                   "return_y": trace.tolist(),
                                   "lifted_t": (lt - t_lift).tolist(),
                                   "lifted_y": (lsx if axis == 0 else lsy)[:, taxel].tolist()}
    out["z_preload"] = z_pre
    return out


def repeat_sequence(lab: Lab, plan: Plan, taxel: int, x0: float, y0: float,
                    progress: ProgressFn) -> dict[str, Any]:
    """``cycles`` presses to ``cycle_depth_mm``; the peak of each for the drift. Lifted
    on a settled skin after the last, the sensor's zero says how far its baseline
    drifted meanwhile (taken out of the peaks by the analysis)."""
    lift_and_tare(lab, plan, taxel, x0, y0, plan.approach_mm)
    t_tare = lab.clock.now()
    z_surface = find_load(lab, plan, plan.approach_mm, plan.contact_kpa) + plan.search_step_mm
    peaks, loads, times = [], [], []
    for c in range(plan.cycles):
        lab.move(z=z_surface - plan.cycle_depth_mm, speed=plan.speed_mm_s,
                 acceleration=plan.acceleration_mm_s2)
        r = lab.hold(plan.cycle_hold_s, min(plan.window_s, plan.cycle_hold_s))
        lab.move(z=z_surface + 0.05, speed=plan.speed_mm_s, acceleration=plan.acceleration_mm_s2)
        lab.clock.sleep(plan.cycle_hold_s, lab.cancel)
        peaks.append(float(r.normal[taxel]))
        loads.append(float(r.stress_kpa[2]))
        times.append(round(r.t1, 4))
        lab.event("char_cycle", cycle=c, peak=peaks[-1], pz=loads[-1])
        progress((c + 1) / plan.cycles, f"cycle {c + 1}/{plan.cycles}")
    lab.move(z=plan.approach_mm, speed=plan.speed_mm_s)
    lab.wait_steady(taxel, plan.settle_s, plan.settle_max_s, plan.steady_per_s)
    zero = lab.read_window(lab.clock.now() - plan.window_s, lab.clock.now())
    return {"peaks": peaks, "loads": loads, "t": times, "tare_t": round(t_tare, 4),
            "zero_t": round(zero.t1, 4), "zero": float(zero.normal[taxel])}
