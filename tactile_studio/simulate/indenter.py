"""A simulated bench: a flat indenter on a stage pressing and dragging the simulated skin.

The ``simulated`` stage and load cell (plugins/sim_stage.py, plugins/sim_force.py) share
one :class:`Bench` per simulated sensor. The sensor consults it as an external load
(``SensorSimulator.external``) for every frame it generates, so the indenter goes through
the simulator's own mechanics: elastomer spread, shear crosstalk, viscoelastic creep and
relaxation, the two-range normal response, per-channel gains.

Skin model (all stresses are the mean over the indenter face, what a load cell measures):
- normal stress = ``normal_stiffness`` x indentation depth (linear skin);
- shear traction = ``shear_stiffness`` x skin displacement, where the skin follows the
  indenter while it moves away from where contact was made, but recovers only partly on
  the way back: it keeps ``slip_offset`` of its largest excursion (slippage / permanent
  set), which is the shear offset after return; lifting the indenter resets it;
- the pressure footprint stays where contact was made (the elastomer shears under it).

Timing: everything is on the simulated sensor's clock (frame index / rate). With the
sensor at ``speed=0`` the bench runs in lockstep: the sensor generates frames only up
to the horizon the procedure asked for (:meth:`Bench.advance_to`), so a run is
deterministic and no frames are wasted while the procedure thinks.
"""

from __future__ import annotations

import threading
import time
import weakref
from dataclasses import dataclass

import numpy as np

from tactile_studio.errors import Cancelled, UserError
from tactile_studio.simulate.contact import Contacts, profile, stress_fields


@dataclass(frozen=True)
class SkinModel:
    """The indenter and the skin's mechanics (the simulated ground truth)."""

    indenter_mm: float = 14.0              # square flat face, side
    normal_stiffness: float = 80.0         # kPa of mean normal stress per mm of depth
    shear_stiffness: float = 1.0           # kPa of mean shear traction per mm of drag
    slip_offset: float = 0.1               # fraction of the peak drag kept after return
    force_noise_n: float = 0.002           # load-cell noise, N (std)

    @property
    def area_mm2(self) -> float:
        return self.indenter_mm ** 2

    @property
    def radius_mm(self) -> float:
        """Radius of the round patch with the face's area (the contact model is round)."""
        return float(np.sqrt(self.area_mm2 / np.pi))

    def footprint_mm2(self) -> float:
        """Integral of the contact profile over the plane: peak kPa x this = force in mN."""
        r = np.linspace(0.0, self.radius_mm + 60.0, 6001)
        g = profile(r, np.full_like(r, self.radius_mm))
        return float(np.trapezoid(2 * np.pi * r * g, r))


class Trajectory:
    """Piecewise-linear stage position over lab time (knots appended by moves)."""

    def __init__(self, start: tuple[float, float, float]) -> None:
        self.t = [0.0]
        self.p = [tuple(float(v) for v in start)]

    @property
    def end_time(self) -> float:
        return self.t[-1]

    @property
    def target(self) -> tuple[float, float, float]:
        return self.p[-1]

    def add_move(self, now: float, target: tuple[float, float, float], speed: float,
                 acceleration: float) -> float:
        """Queue a straight move after any pending one; returns when it ends."""
        start_t = max(now, self.t[-1])
        here = self.at(np.array([start_t]))[0]
        dist = float(np.linalg.norm(np.asarray(target) - here))
        dur = 0.0 if dist == 0 else dist / speed + (speed / acceleration if acceleration > 0 else 0)
        self.t += [start_t, start_t + dur]
        self.p += [tuple(here), tuple(float(v) for v in target)]
        return start_t + dur

    def at(self, times: np.ndarray) -> np.ndarray:
        """(n, 3) positions at ``times``."""
        t = np.asarray(self.t)
        p = np.asarray(self.p)
        return np.stack([np.interp(times, t, p[:, k]) for k in range(3)], axis=1)

    def prune(self, before: float) -> None:
        """Forget knots no frame can need any more (keeps interpolation cheap)."""
        while len(self.t) > 2 and self.t[1] < before:
            self.t.pop(0)
            self.p.pop(0)


class Bench:
    """The indenter, its stage trajectory and the skin state over one simulated sensor."""

    def __init__(self, sim, skin: SkinModel | None = None,  # noqa: ANN001 - SensorSimulator
                 home: tuple[float, float, float] = (0.0, 0.0, 5.0)) -> None:
        self.sim = sim
        self.skin = skin or SkinModel()
        self.rate = float(sim.rate)
        self.traj = Trajectory(home)
        self._footprint = self.skin.footprint_mm2()
        self._cond = threading.Condition()
        self.horizon: int | None = None   # lockstep limit (frames), None = free running
        self._contact = False
        self._anchor = np.zeros(2)
        self._peak = np.zeros(2)
        self._log_t: list[np.ndarray] = []
        self._log_f: list[np.ndarray] = []

    # ---- the lab clock ---------------------------------------------------------------
    def now(self) -> float:
        """Lab time = the time of the next frame the sensor will generate."""
        return self.sim.frame / self.rate

    def advance_to(self, t: float, cancel=None, timeout_s: float = 60.0) -> None:  # noqa: ANN001
        """Let the sensor generate frames up to lab time ``t`` and wait until it has."""
        target = int(np.ceil(t * self.rate - 1e-9))
        with self._cond:
            if self.horizon is not None:
                self.horizon = max(self.horizon, target)
                self._cond.notify_all()
            deadline = time.monotonic() + timeout_s
            while self.sim.frame < target:
                if cancel is not None and cancel.cancelled:
                    raise Cancelled("cancelled")
                left = deadline - time.monotonic()
                if left <= 0:
                    raise UserError(f"simulated bench: the sensor stopped producing frames "
                                    f"(at {self.sim.frame / self.rate:.2f} s, "
                                    f"waiting for {t:.2f} s)")
                self._cond.wait(min(left, 0.02))

    def lockstep(self, on: bool) -> None:
        """Lockstep pacing (for a sensor at speed 0) on or off."""
        with self._cond:
            self.horizon = self.sim.frame if on else None
            self._cond.notify_all()

    # ---- hooks the simulated sensor calls --------------------------------------------
    def allowed(self, next_frame: int, wanted: int, timeout_s: float) -> int:
        """How many frames the sensor may generate now (lockstep), waiting up to
        ``timeout_s`` for the procedure to move the horizon."""
        with self._cond:
            self._cond.notify_all()  # frames generated so far are visible now
            if self.horizon is None:
                return wanted
            if self.horizon <= next_frame:
                self._cond.wait(timeout_s)
            return max(0, min(wanted, (self.horizon or next_frame) - next_frame))

    def contacts(self, frames: np.ndarray) -> Contacts | None:
        """The indenter's contact patch at absolute ``frames`` (None while lifted)."""
        times = np.asarray(frames, dtype=np.float64) / self.rate
        with self._cond:
            pos = self.traj.at(times)
            self.traj.prune(times[0] - 1.0)
            load, sx, sy, ax, ay = self._mechanics(pos)
        ratio = self.skin.area_mm2 / self._footprint  # peak kPa per mean kPa
        forces = np.stack([sx, sy, load], axis=1) * self.skin.area_mm2 * 1e-3  # kPa*mm2 -> N
        with self._cond:
            self._log_t.append(times)
            self._log_f.append(forces)
            if len(self._log_t) > 4000:  # nobody reads the load cell: keep the newest
                del self._log_t[:2000], self._log_f[:2000]
        if not np.any(load > 0):
            return None
        return Contacts.make(len(times), ax, ay, self.skin.radius_mm, load * ratio,
                             sx * ratio, sy * ratio)

    def _mechanics(self, pos: np.ndarray) -> tuple[np.ndarray, ...]:
        """Mean normal stress, shear tractions and the footprint centre per frame."""
        n = len(pos)
        depth = np.maximum(0.0, -pos[:, 2])
        load = self.skin.normal_stiffness * depth
        sx, sy, ax, ay = np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)
        keep, k = self.skin.slip_offset, self.skin.shear_stiffness
        for i in range(n):  # the skin's memory makes this sequential
            if depth[i] <= 0:
                self._contact = False
                ax[i], ay[i] = pos[i, 0], pos[i, 1]
                continue
            if not self._contact:
                self._contact = True
                self._anchor = pos[i, :2].copy()
                self._peak = np.zeros(2)
            u = pos[i, :2] - self._anchor
            grow = (np.abs(u) >= np.abs(self._peak)) | (np.sign(u) * np.sign(self._peak) < 0)
            self._peak = np.where(grow, u, self._peak)
            s = (1 - keep) * u + keep * self._peak
            sx[i], sy[i] = k * s[0], k * s[1]
            ax[i], ay[i] = self._anchor
        return load, sx, sy, ax, ay

    def forces_since(self) -> tuple[np.ndarray, np.ndarray]:
        """True (t, forces N) at every frame generated since the last call."""
        with self._cond:
            t = np.concatenate(self._log_t) if self._log_t else np.empty(0)
            f = np.concatenate(self._log_f) if self._log_f else np.empty((0, 3))
            self._log_t, self._log_f = [], []
        return t, f


_BENCHES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def bench_for(sim, skin: SkinModel | None = None) -> Bench:  # noqa: ANN001
    """The bench over ``sim`` (created and hooked into the sensor on first use)."""
    bench = _BENCHES.get(sim)
    if bench is None or (skin is not None and bench.skin != skin):
        bench = Bench(sim, skin)
        _BENCHES[sim] = bench
        sim.external = bench
    return bench


def _static_signals(sim, contacts: Contacts):  # noqa: ANN001, ANN202
    """Noise-free, fully relaxed per-taxel signals for a static indenter load."""
    from tactile_studio.sensor.characterise import taxel_signals

    normal, sx, sy = stress_fields(contacts, sim._points, sim._centre)
    c = sim.config.crosstalk
    eff = np.concatenate([normal, sx + c * sy, sy + c * sx], axis=1)
    raw = sim.baseline * (1.0 - sim._relative_change(eff))
    return taxel_signals(sim.layout, raw, sim.baseline)


def true_parameters(sim, skin: SkinModel, taxel: int, max_depth_mm: float = 0.8,  # noqa: ANN001
                    preload_kpa: float = 2.5) -> dict[str, float]:
    """The ground truth a characterisation of ``taxel`` should recover, probed from the
    simulator's own static response (no noise, no creep, no drift): normal slopes at
    the bottom and the top of the range and where the two lines cross, shear slopes
    under the preload, the worst normal crosstalk at full depth, and the skin's
    relaxation time and slip offset. Units as in characterisation.json."""
    lay = sim.layout
    x, y = lay.taxel_centre_mm(*lay.taxel_rc(taxel))
    ratio = skin.area_mm2 / skin.footprint_mm2()

    def signals(p: float, tx: float = 0.0, ty: float = 0.0):  # noqa: ANN202 - mean kPa in
        return _static_signals(sim, Contacts.make(1, x, y, skin.radius_mm, p * ratio,
                                                  tx * ratio, ty * ratio))

    p_max = skin.normal_stiffness * max_depth_mm
    n0, n1 = signals(0.0)[0][0, taxel], signals(1.0)[0][0, taxel]
    na, nb = signals(0.9 * p_max)[0][0, taxel], signals(p_max)[0][0, taxel]
    low, high = n1 - n0, (nb - na) / (0.1 * p_max)
    breakpoint = (na - 0.9 * p_max * high - n0) / (low - high)
    full = signals(p_max)[0][0]
    from tactile_studio.sensor.characterise import neighbours

    cross = max(full[t] / full[taxel] for t in neighbours(lay, taxel).values())
    base = signals(preload_kpa)
    sx = signals(preload_kpa, tx=1.0)[1][0, taxel] - base[1][0, taxel]
    sy = signals(preload_kpa, ty=1.0)[2][0, taxel] - base[2][0, taxel]
    return {"normal_sensitivity_low": float(low), "normal_sensitivity_high": float(high),
            "breakpoint_kpa": float(breakpoint), "shear_sensitivity_x": float(sx),
            "shear_sensitivity_y": float(sy), "crosstalk_max": float(cross),
            "relaxation_s": float(sim.config.relaxation_s),
            "shear_offset": float(skin.slip_offset)}
