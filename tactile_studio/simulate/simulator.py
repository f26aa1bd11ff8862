"""The simulated ShearSense sensor: contact patches in, raw 16-bit counts out.

Pipeline for a batch of frames (all vectorised over frames except one tiny recursive
filter):

1. the schedule says which trial runs at each frame; its gesture model gives contact
   patches; contact mechanics gives normal stress at all 180 channel points and shear
   traction at the 36 taxel centres (kPa);
2. shear-axis crosstalk mixes a fraction of each shear axis into the other;
3. viscoelasticity (a standard-linear-solid creep): a fraction ``creep`` of the response
   follows the load through a first-order lag of ``relaxation_s``, so a step load
   creeps up over ~3 s and a release leaves a decaying residue (apparent hysteresis);
4. each channel's relative change is the calibration's inverse (``normal_rel``) of its
   local normal stress; the outer channels of an axis pair move apart by the shear
   (scaled so :func:`tactile_studio.sensor.decode.decode` returns the shear in kPa);
   per-channel gain spread and faults scale it;
5. counts = drifting baseline x (1 - relative change) + Gaussian noise, clipped to
   0..65535 and rounded to uint16.

Determinism rule: every random draw is keyed by the seed and a frame or trial index
(noise comes in fixed blocks of frames, trial details from the trial's key), and the
only state carried between calls is the lag filter, updated frame by frame. So the same
settings, seed and (frame, command) history give bit-identical frames however
:meth:`SensorSimulator.step` calls are sized.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from tactile_studio.errors import UserError
from tactile_studio.sensor.layout import CENTRE, SHEARSENSE_6X6, X_NEG, X_POS, Y_NEG, Y_POS, Layout
from tactile_studio.simulate import population
from tactile_studio.simulate.contact import Contacts, channel_points, stress_fields
from tactile_studio.simulate.faults import add_delamination
from tactile_studio.simulate.gestures import IDLE, TrialParams, envelope
from tactile_studio.simulate.population import DEFAULT_DIFFICULTY, DIFFICULTIES, SURFACES
from tactile_studio.simulate.schedule import PRESS, Schedule, Trial

FAULTS = ("none", "dead_taxel", "stuck_channel", "worn", "delaminated")
_NOISE_BLOCK = 512
_MAX_KPA = 60.0  # the dielectric bottoms out: beyond this the reading saturates


@dataclass(frozen=True)
class SimConfig:
    """Every knob of the simulated sensor (see docs/simulator.md)."""

    rate: float = 43.0            # frames per second of simulated time
    seed: int = 0                 # sensor identity, noise and trial randomness
    gesture: str = "auto"         # background mode: auto | idle | a gesture name
    intensity: float = 1.0        # scales every gesture's load and traction
    speed: float = 1.0            # scales every gesture's tempo
    style_seed: int = 0           # the virtual participant's personal style
    noise: float = 20.0           # Gaussian noise, counts (std)
    drift: float = 0.002          # slow baseline wander, relative amplitude
    crosstalk: float = 0.07       # fraction of each shear axis leaking into the other
    relaxation_s: float = 3.0     # viscoelastic time constant
    creep: float = 0.2            # fraction of the response that lags the load
    gain_spread: float = 0.02     # per-channel sensitivity spread (relative std)
    fault: str = "none"           # none | dead_taxel | stuck_channel | worn | delaminated
    fault_taxel: int = 14         # the taxel the fault hits (worn: plus three others)
    sensitivity_spread: float = 0.0  # per-taxel sensitivity spread (relative std)
    difficulty: str = DEFAULT_DIFFICULTY  # easy | real | people | hard: how varied people are
    surface: str = "flat"         # flat | pillow (spreads and damps the load)
    layout: Layout = SHEARSENSE_6X6


class SensorSimulator:
    """Generates raw frames of a ShearSense-style sensor, frame index by frame index.

    Not thread-safe by itself: the device plugin wraps it in a lock.
    """

    def __init__(self, config: SimConfig | None = None, **overrides: object) -> None:
        cfg = replace(config or SimConfig(), **overrides)  # type: ignore[arg-type]
        if not cfg.layout.has_shear or cfg.layout.calibration is None:
            raise UserError("the simulator needs a calibrated 5-channel layout, "
                            f"not {cfg.layout.name}")
        if cfg.fault not in FAULTS:
            raise UserError(f"unknown fault {cfg.fault!r} (known: {', '.join(FAULTS)})")
        if not 0 <= cfg.fault_taxel < cfg.layout.n_taxels:
            raise UserError(f"fault_taxel {cfg.fault_taxel} is not a taxel "
                            f"(0..{cfg.layout.n_taxels - 1})")
        if cfg.difficulty not in DIFFICULTIES:
            raise UserError(f"unknown difficulty {cfg.difficulty!r} "
                            f"(known: {', '.join(DIFFICULTIES)})")
        if cfg.surface not in SURFACES:
            raise UserError(f"unknown surface {cfg.surface!r} (known: {', '.join(SURFACES)})")
        self.config = cfg
        self.layout = lay = cfg.layout
        self.rate = float(cfg.rate)
        self.seed = int(cfg.seed) & 0xFFFFFFFF
        self.frame = 0  # index of the next frame step() will produce
        nt, k = lay.n_taxels, lay.channels_per_taxel
        self._points = channel_points(lay)
        self._centre = np.arange(nt) * k + CENTRE
        self._xpos, self._xneg = np.arange(nt) * k + X_POS, np.arange(nt) * k + X_NEG
        self._ypos, self._yneg = np.arange(nt) * k + Y_POS, np.arange(nt) * k + Y_NEG

        # The sensor's identity: baselines, gains, drift, faults (seeded, never re-drawn).
        rng = np.random.default_rng([self.seed, 0x5E45])
        taxel_base = rng.uniform(22000, 36000, nt)
        self.baseline = np.repeat(taxel_base, k) * (1 + rng.normal(0, 0.03, nt * k))
        self.gain = 1 + rng.normal(0, cfg.gain_spread, nt * k)
        self.gain *= population.sensor_gains(self.seed, nt * k, cfg.difficulty)
        self._drift_period = rng.uniform(120, 400, nt * k)
        self._drift_phase = rng.uniform(0, 2 * np.pi, nt * k)
        self._drift_common = rng.uniform(0, 2 * np.pi)
        self.taxel_gain = np.ones(nt)
        self.stuck_channel: int | None = None
        self.stuck_value = 0
        if cfg.fault == "dead_taxel":
            self.taxel_gain[cfg.fault_taxel] = 0.0
        elif cfg.fault == "worn":
            others = rng.choice(np.delete(np.arange(nt), cfg.fault_taxel), 3, replace=False)
            self.taxel_gain[others] = rng.uniform(0.55, 0.8, 3)
            self.taxel_gain[cfg.fault_taxel] = 0.45
        elif cfg.fault == "stuck_channel":
            self.stuck_channel = cfg.fault_taxel * k + CENTRE
            self.stuck_value = int(round(0.95 * self.baseline[self.stuck_channel]))
        if cfg.sensitivity_spread:  # own stream: seeds without a spread are unchanged
            spread = np.random.default_rng([self.seed, 0x5E45, 1]).normal(
                0, cfg.sensitivity_spread, nt)
            self.taxel_gain *= np.clip(1 + spread, 0.2, None)
        b = self.baseline
        # Shear scale so decode() (which divides by C3*C3' and multiplies by C_a*C_b) is
        # exactly inverted: see _shear in tactile_studio/sensor/decode.py.
        self._kx = b[self._centre] ** 2 / (b[self._xneg] * b[self._xpos])
        self._ky = b[self._centre] ** 2 / (b[self._yneg] * b[self._ypos])

        self._lag = np.zeros(nt * k + 2 * nt)
        self._alpha = float(np.exp(-1.0 / (self.rate * max(cfg.relaxation_s, 1e-6))))
        self._noise_cache: dict[int, np.ndarray] = {}
        self._params_cache: dict[tuple, TrialParams] = {}
        # An external load consulted for every frame (the characterisation bench, see
        # simulate/indenter.py): an object with ``contacts(frames) -> Contacts | None``.
        self.external = None
        self._mode, self._style = cfg.gesture, int(cfg.style_seed)
        self._intensity, self._speed = float(cfg.intensity), float(cfg.speed)
        self.schedule = Schedule(self.rate, self.seed)
        try:
            self.schedule.set_mode(0, cfg.gesture, self._style, self._intensity, self._speed)
        except ValueError as exc:
            raise UserError(str(exc)) from None

    # ---- control (keyed by frame index) ----------------------------------------------
    def _when(self, at_frame: int | None) -> int:
        if at_frame is None:
            return self.frame
        if at_frame < self.frame:
            raise ValueError(f"frame {at_frame} was already generated (next is {self.frame})")
        return int(at_frame)

    def perform(self, gesture: str, duration_s: float = 2.0, intensity: float | None = None,
                speed: float | None = None, at_frame: int | None = None,
                shift_mm: tuple[float, float] = (0.0, 0.0)) -> Trial:
        """Perform ``gesture`` for ``duration_s`` from ``at_frame`` (default: the next frame),
        ``shift_mm`` (x, y) away from where this person usually touches."""
        return self.schedule.add_trial(
            gesture, self._when(at_frame), round(duration_s * self.rate),
            self._intensity if intensity is None else float(intensity),
            self._speed if speed is None else float(speed), self._style, shift_mm=shift_mm)

    def press(self, x_mm: float, y_mm: float, load_kpa: float, radius_mm: float = 5.0,
              shear_x: float = 0.0, shear_y: float = 0.0, duration_s: float = 2.0,
              ramp_s: float = 0.05, at_frame: int | None = None) -> Trial:
        """A static press (an indenter, a known weight): no tremor, no style.

        For characterisation and wellness checks; ``radius_mm >= 1000`` loads the whole
        sensor uniformly. Ground truth reads 'press'.
        """
        return self.schedule.add_trial(
            PRESS, self._when(at_frame), round(duration_s * self.rate), 1.0, 1.0, self._style,
            press=(float(x_mm), float(y_mm), float(radius_mm), float(load_kpa),
                   float(shear_x), float(shear_y), float(ramp_s)))

    def contacts(self, trial: Trial, frames: np.ndarray) -> Contacts:
        """The true contact patches of ``trial`` at absolute frame indices ``frames``."""
        t = (np.asarray(frames) - trial.start) / self.rate
        dur = trial.frames / self.rate
        if trial.press is not None:
            x, y, radius, load, sx, sy, ramp = trial.press
            env = envelope(t, 0.0, dur, ramp) if ramp > 0 else ((t >= 0) & (t < dur)) * 1.0
            return Contacts.make(len(t), x, y, radius, load * env, sx * env, sy * env)
        return population.render(trial.gesture, t, dur, self._params(trial),
                                 trial.style_seed, self.config.difficulty, self.config.surface)

    def set_gesture(self, mode: str, at_frame: int | None = None,
                    intensity: float | None = None, speed: float | None = None) -> None:
        """Background mode from ``at_frame`` on: 'auto', 'idle' or a gesture repeated."""
        if intensity is not None:
            self._intensity = float(intensity)
        if speed is not None:
            self._speed = float(speed)
        seg = self.schedule.set_mode(self._when(at_frame), mode, self._style,
                                     self._intensity, self._speed)
        self._mode = seg.mode

    def set_style(self, style_seed: int, at_frame: int | None = None) -> None:
        """Switch to another virtual participant (their later trials use the new style)."""
        self._style = int(style_seed)
        self.schedule.set_mode(self._when(at_frame), self._mode, self._style,
                               self._intensity, self._speed)

    def gesture_at(self, frame: int) -> str:
        """Ground truth: the gesture scheduled at ``frame`` ('idle' if none)."""
        return self.schedule.gesture_at(frame)

    @property
    def current_gesture(self) -> str:
        """Ground truth at the newest generated frame ('idle' before the first)."""
        return self.gesture_at(self.frame - 1) if self.frame > 0 else IDLE

    # ---- generation ------------------------------------------------------------------
    def step(self, n: int) -> np.ndarray:
        """The next ``n`` frames as raw counts, (n, n_channels) uint16."""
        n = int(n)
        lay, f0 = self.layout, self.frame
        nc, nt = lay.n_channels, lay.n_taxels
        if n <= 0:
            return np.empty((0, nc), dtype=np.uint16)
        load = np.zeros((n, nc + 2 * nt))
        for trial, lo, hi in self.schedule.pieces(f0, f0 + n):
            if trial is None or trial.gesture == IDLE:
                continue
            contacts = self.contacts(trial, np.arange(lo, hi))
            normal, sx, sy = stress_fields(contacts, self._points, self._centre)
            c = self.config.crosstalk
            load[lo - f0:hi - f0] = np.concatenate([normal, sx + c * sy, sy + c * sx], axis=1)
        if self.external is not None:
            extra = self.external.contacts(np.arange(f0, f0 + n))
            if extra is not None:
                normal, sx, sy = stress_fields(extra, self._points, self._centre)
                c = self.config.crosstalk
                load += np.concatenate([normal, sx + c * sy, sy + c * sx], axis=1)
        if self.config.fault == "delaminated":
            add_delamination(load, self.config.fault_taxel, self._centre, nc, nt)
        eff = self._viscoelastic(load)
        rel = self._relative_change(eff)
        t = np.arange(f0, f0 + n) / self.rate
        raw = self._counts(rel, t, f0)
        self.frame = f0 + n
        return raw

    def _params(self, trial: Trial) -> TrialParams:
        key = (*trial.key, trial.style_seed, trial.start)
        params = self._params_cache.get(key)
        if params is None:
            rng = np.random.default_rng([self.seed, trial.style_seed & 0xFFFFFFFF, *trial.key])
            params = population.trial_params(rng, trial.gesture, trial.style_seed,
                                             trial.intensity, trial.speed,
                                             self.config.difficulty)
            if trial.shift_mm != (0.0, 0.0):
                params = replace(params, cx=params.cx + trial.shift_mm[0],
                                 cy=params.cy + trial.shift_mm[1])
            if len(self._params_cache) > 64:
                self._params_cache.clear()
            self._params_cache[key] = params
        return params

    def _viscoelastic(self, load: np.ndarray) -> np.ndarray:
        """(1 - creep) * load + creep * lag(load): creep under a step, residue after."""
        creep = self.config.creep
        if creep <= 0:
            return load
        a, lag = self._alpha, self._lag
        out = np.empty_like(load)
        for i in range(load.shape[0]):  # frame by frame: identical for any batching
            lag = a * lag + (1.0 - a) * load[i]
            out[i] = lag
        self._lag = lag
        return (1.0 - creep) * load + creep * out

    def _relative_change(self, eff: np.ndarray) -> np.ndarray:
        lay = self.layout
        nc, nt = lay.n_channels, lay.n_taxels
        normal = np.clip(eff[:, :nc], 0.0, _MAX_KPA)
        rel = lay.calibration.normal_rel(normal)
        slope = lay.calibration.shear_slope
        one_minus_r3 = 1.0 - rel[:, self._centre]
        dx = 0.5 * slope * eff[:, nc:nc + nt] * self._kx * one_minus_r3
        dy = 0.5 * slope * eff[:, nc + nt:] * self._ky * one_minus_r3
        rel[:, self._xpos] += dx
        rel[:, self._xneg] -= dx
        rel[:, self._ypos] += dy
        rel[:, self._yneg] -= dy
        return rel * (self.gain * np.repeat(self.taxel_gain, lay.channels_per_taxel))

    def _counts(self, rel: np.ndarray, t: np.ndarray, f0: int) -> np.ndarray:
        cfg = self.config
        base = self.baseline
        if cfg.drift:
            wander = (0.6 * np.sin(2 * np.pi * t[:, None] / 600.0 + self._drift_common)
                      + 0.4 * np.sin(2 * np.pi * t[:, None] / self._drift_period
                                     + self._drift_phase))
            base = base * (1.0 + cfg.drift * wander)
        raw = base * (1.0 - rel)
        if cfg.noise:
            raw += cfg.noise * self._noise(f0, len(t))
        if self.stuck_channel is not None:
            raw[:, self.stuck_channel] = self.stuck_value
        return np.rint(np.clip(raw, 0, 65535)).astype(np.uint16)

    def _noise(self, f0: int, n: int) -> np.ndarray:
        """Standard normal noise for frames f0..f0+n, drawn in fixed blocks of frames."""
        nc = self.layout.n_channels
        out = np.empty((n, nc))
        f = f0
        while f < f0 + n:
            block, lo = divmod(f, _NOISE_BLOCK)
            take = min(_NOISE_BLOCK - lo, f0 + n - f)
            data = self._noise_cache.get(block)
            if data is None:
                rng = np.random.default_rng([self.seed, 0x401, block])
                data = rng.standard_normal((_NOISE_BLOCK, nc))
                self._noise_cache = {block: data}
            out[f - f0:f - f0 + take] = data[lo:lo + take]
            f += take
        return out
