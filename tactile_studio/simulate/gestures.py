"""The nine protocol gestures as spatio-temporal contact patterns, plus idle.

Each gesture turns time since the trial started into contact patches (see
:mod:`tactile_studio.simulate.contact`). What varies between performances is drawn
once per trial into :class:`TrialParams` from a seeded generator, and what varies
between people lives in :class:`Style` (seeded by the participant's style seed), so the
same participant does a gesture recognisably the same way every time while two
participants differ — which is what makes leave-one-participant-out harder than a
random split, as in the paper.

Sensor frame: x, y in mm from the top-left taxel centre; the 6x6 ShearSense array spans
0..80 mm in both directions, so (40, 40) is the middle. Loads in kPa, tractions in kPa.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from tactile_studio.simulate.contact import Contacts

GESTURE_NAMES: tuple[str, ...] = (
    "Poke", "Wide Pinch", "Heavy Pat", "Twist", "Back & Forth Rub", "Isometric Rub",
    "Circular Stroke", "Constant Touch", "Tickle",
)
IDLE = "idle"
CENTRE_MM = (40.0, 40.0)
_TWO_PI = 2.0 * np.pi


@dataclass(frozen=True)
class Style:
    """A virtual participant's personal way of touching, fixed by ``seed``."""

    seed: int
    offset_x: float   # mm: where on the sensor they tend to touch
    offset_y: float
    size: float       # finger/hand size factor
    force: float      # how hard they press
    tempo: float      # how fast they move
    jitter: float     # mm of hand tremor/wander
    angle: float      # preferred stroke direction (rad, 0 = along x)

    @classmethod
    def from_seed(cls, seed: int) -> Style:
        rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 0x57E1])
        return cls(
            seed=int(seed),
            offset_x=float(rng.uniform(-8, 8)), offset_y=float(rng.uniform(-8, 8)),
            size=float(rng.uniform(0.85, 1.2)), force=float(rng.uniform(0.75, 1.35)),
            tempo=float(rng.uniform(0.8, 1.25)), jitter=float(rng.uniform(0.3, 1.5)),
            angle=float(rng.uniform(-0.45, 0.45)),
        )


@dataclass(frozen=True)
class TrialParams:
    """Everything random about one performance, drawn when the trial is created."""

    cx: float
    cy: float
    size: float
    force: float
    tempo: float
    jitter: float
    angle: float
    phases: tuple[float, ...]
    rng_seed: tuple[int, ...]
    # how far into its first beat a rhythmic gesture's first finger may start (1: anywhere
    # in it; a population's hand that starts at once sets less)
    onset: float = 1.0
    # the gesture's own clock for its motion (a hand whose pace drifts; None: the trial's).
    # When the hand touches and lets go stays on the trial's clock, so a performance ends
    # when it is over whatever its pace did.
    pace: Callable[[np.ndarray], np.ndarray] | None = field(default=None, compare=False)

    @classmethod
    def draw(cls, rng: np.random.Generator, style: Style, intensity: float,
             speed: float) -> TrialParams:
        return cls(
            cx=CENTRE_MM[0] + style.offset_x + float(rng.uniform(-6, 6)),
            cy=CENTRE_MM[1] + style.offset_y + float(rng.uniform(-6, 6)),
            size=style.size * float(rng.uniform(0.93, 1.07)),
            force=style.force * intensity * float(rng.uniform(0.85, 1.15)),
            tempo=max(style.tempo * speed * float(rng.uniform(0.9, 1.1)), 1e-3),
            jitter=style.jitter,
            angle=style.angle + float(rng.uniform(-0.3, 0.3)),
            phases=tuple(float(v) for v in rng.uniform(0, _TWO_PI, 8)),
            rng_seed=tuple(int(v) for v in rng.integers(0, 2**31, 2)),
        )

    def motion(self, t: np.ndarray) -> np.ndarray:
        """Trial time ``t`` on the gesture's own clock (the same without a drifting pace)."""
        return t if self.pace is None else self.pace(t)

    def motion_length(self, dur: float) -> float:
        """How long a performance of ``dur`` s lasts on the gesture's own clock (how many
        pats or taps fit in it)."""
        return float(self.motion(np.asarray(dur, dtype=np.float64)))

    def rng(self) -> np.random.Generator:
        """A generator for per-gesture details (tickle spots, pat offsets), same each call."""
        return np.random.default_rng(list(self.rng_seed))

    def wobble(self, t: np.ndarray, k: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """Slow smooth hand wander in mm (tremor plus drift), different per trial."""
        ph = self.phases
        wx = (np.sin(_TWO_PI * 0.7 * t + ph[k % 8])
              + 0.5 * np.sin(_TWO_PI * 2.3 * t + ph[(k + 1) % 8]))
        wy = (np.sin(_TWO_PI * 0.9 * t + ph[(k + 2) % 8])
              + 0.5 * np.sin(_TWO_PI * 1.9 * t + ph[(k + 3) % 8]))
        return self.jitter * wx / 1.5, self.jitter * wy / 1.5


def envelope(t: np.ndarray, start: float, end: float, ramp: float) -> np.ndarray:
    """0 outside [start, end], 1 inside, with raised-cosine ramps of ``ramp`` s."""
    ramp = max(min(ramp, 0.5 * (end - start)), 1e-6)
    up = np.clip((t - start) / ramp, 0.0, 1.0)
    down = np.clip((end - t) / ramp, 0.0, 1.0)
    return 0.5 - 0.5 * np.cos(np.pi * np.minimum(up, down))


def pulse(t: np.ndarray, start: float, width: float) -> np.ndarray:
    """A sin^2 bump from ``start`` lasting ``width`` s (a tap's force profile)."""
    u = (t - start) / max(width, 1e-6)
    return np.where((u >= 0) & (u <= 1), np.sin(np.pi * np.clip(u, 0, 1)) ** 2, 0.0)


def _unit(angle: float) -> tuple[float, float]:
    return float(np.cos(angle)), float(np.sin(angle))


# ---- the nine gestures ---------------------------------------------------------------

def poke(t: np.ndarray, dur: float, p: TrialParams) -> Contacts:
    """One brief fingertip press, small area, moderate force."""
    start = 0.12 + 0.2 * (p.phases[0] / _TWO_PI)
    width = min(0.35 / p.tempo, dur - start - 0.02)
    wx, wy = p.wobble(t)
    load = 13.0 * p.force * pulse(t, start, width)
    ux, uy = _unit(p.phases[1])  # a slight sideways slip while pressing
    return Contacts.make(len(t), p.cx + wx, p.cy + wy, 4.5 * p.size, load,
                         0.3 * ux * load / 13.0, 0.3 * uy * load / 13.0)


def wide_pinch(t: np.ndarray, dur: float, p: TrialParams) -> Contacts:
    """Two fingertips land far apart and slide towards each other (convergent)."""
    ux, uy = _unit(p.angle)
    start, move = 0.1, 0.9 / p.tempo
    u = np.clip((p.motion(t) - start) / move, 0.0, 1.0)
    span = 52.0 * p.size - 14.0
    half = 0.5 * (52.0 * p.size - u * u * (3 - 2 * u) * span)  # smoothstep closing
    closing = -0.5 * span * 6 * u * (1 - u) / move  # d(half)/dt, mm/s (pointwise in t)
    env = envelope(t, start - 0.05, min(dur - 0.1, start + move + 0.6 / p.tempo), 0.12)
    load = 8.0 * p.force * env
    drag = env * p.force * (0.8 + 2.0 * np.clip(-closing / 40.0, 0.0, 1.0))
    wx, wy = p.wobble(t)
    a = Contacts.make(len(t), p.cx - ux * half + wx, p.cy - uy * half + wy, 4.5 * p.size,
                      load, ux * drag, uy * drag)
    b = Contacts.make(len(t), p.cx + ux * half + wx, p.cy + uy * half + wy, 4.5 * p.size,
                      load, -ux * drag, -uy * drag)
    return Contacts.join([a, b])


def heavy_pat(t: np.ndarray, dur: float, p: TrialParams) -> Contacts:
    """A palm slapping down hard and briefly, several times."""
    period, width = 0.45 / p.tempo, 0.16 / p.tempo
    rng = p.rng()
    m = p.motion(t)
    starts = np.arange(0.1, p.motion_length(dur) - width, period)
    load = np.zeros_like(t)
    x = np.full_like(t, p.cx)
    y = np.full_like(t, p.cy)
    for s0 in starts:
        bump = pulse(m, s0, width)
        ox, oy = rng.uniform(-4, 4, 2)
        load += bump
        inside = (m >= s0) & (m <= s0 + width)
        x[inside] += ox
        y[inside] += oy
    if p.pace is not None:  # a drifting pat still lets go by the performance's end
        load *= np.clip((dur - 0.05 - t) / 0.1, 0.0, 1.0)
    return Contacts.make(len(t), x, y, 26.0 * p.size, 24.0 * p.force * load)


def twist(t: np.ndarray, dur: float, p: TrialParams) -> Contacts:
    """A thumb pad pressed in place and rotated back and forth (rotational shear)."""
    env = envelope(t, 0.1, dur - 0.1, 0.15)
    turn = np.sin(_TWO_PI * 1.0 * p.tempo * (p.motion(t) - 0.1) + 0.3 * p.phases[0])
    wx, wy = p.wobble(t)
    # A pure rotation nets no shear on the taxel under its axis: the signal is the
    # tangential drag on the neighbouring taxels, hence the broad, fleshy thumb pad.
    return Contacts.make(len(t), p.cx + 0.3 * wx, p.cy + 0.3 * wy, 10.5 * p.size,
                         9.0 * p.force * env, 0.0, 0.0, 4.0 * p.force * env * turn)


def back_forth_rub(t: np.ndarray, dur: float, p: TrialParams) -> Contacts:
    """A fingertip sliding back and forth along a line; shear follows the motion."""
    ux, uy = _unit(p.angle)
    env = envelope(t, 0.1, dur - 0.1, 0.15)
    w = _TWO_PI * 2.0 * p.tempo
    amp = 14.0 * p.size
    m = p.motion(t)
    pos = amp * np.sin(w * (m - 0.1))
    vel = amp * w * np.cos(w * (m - 0.1))
    drag = 2.4 * p.force * env * np.tanh(vel / 25.0)
    wx, wy = p.wobble(t)
    return Contacts.make(len(t), p.cx + ux * pos + wx, p.cy + uy * pos + wy, 6.0 * p.size,
                         7.0 * p.force * env, ux * drag, uy * drag)


def isometric_rub(t: np.ndarray, dur: float, p: TrialParams) -> Contacts:
    """A fingertip pressed in place, pushing back and forth without sliding."""
    ux, uy = _unit(p.angle)
    env = envelope(t, 0.1, dur - 0.1, 0.15)
    drag = 2.6 * p.force * env * np.sin(_TWO_PI * 2.2 * p.tempo * (p.motion(t) - 0.1))
    wx, wy = p.wobble(t)
    return Contacts.make(len(t), p.cx + 0.3 * wx, p.cy + 0.3 * wy, 6.0 * p.size,
                         10.0 * p.force * env, ux * drag, uy * drag)


def circular_stroke(t: np.ndarray, dur: float, p: TrialParams) -> Contacts:
    """A fingertip stroking round a circle; shear is tangential, along the motion."""
    direction = 1.0 if p.phases[2] < np.pi else -1.0
    env = envelope(t, 0.1, dur - 0.1, 0.15)
    phi = p.phases[3] + direction * _TWO_PI * 1.1 * p.tempo * (p.motion(t) - 0.1)
    rc = 13.0 * p.size
    tx, ty = -np.sin(phi) * direction, np.cos(phi) * direction
    drag = 1.8 * p.force * env
    return Contacts.make(len(t), p.cx + rc * np.cos(phi), p.cy + rc * np.sin(phi),
                         5.5 * p.size, 6.0 * p.force * env, tx * drag, ty * drag)


def constant_touch(t: np.ndarray, dur: float, p: TrialParams) -> Contacts:
    """A palm (or flat fingers) resting with steady pressure."""
    env = envelope(t, 0.1, dur - 0.05, 0.25)
    breathe = 1.0 + 0.03 * np.sin(_TWO_PI * 0.8 * t + p.phases[4])
    wx, wy = p.wobble(t)
    return Contacts.make(len(t), p.cx + 0.3 * wx, p.cy + 0.3 * wy, 20.0 * p.size,
                         9.0 * p.force * env * breathe)


def tickle(t: np.ndarray, dur: float, p: TrialParams) -> Contacts:
    """Four fingertips flicking lightly and fast over scattered spots."""
    rng = p.rng()
    m = p.motion(t)
    beats = p.motion_length(dur)
    parts = []
    for k in range(4):
        period = float(rng.uniform(0.17, 0.26)) / p.tempo
        phase = float(rng.uniform(0, period)) * (p.onset if k == 0 else 1.0)
        base = rng.uniform(-18, 18, 2) * p.size
        n_taps = int(beats / period) + 2
        offs = rng.uniform(-5, 5, (n_taps, 2))
        dirs = rng.uniform(0, _TWO_PI, n_taps)
        tau = m - 0.05 - phase
        idx = np.clip(np.floor(tau / period).astype(int), 0, n_taps - 1)
        frac = tau / period - np.floor(tau / period)
        on = (tau >= 0) & (t < dur - 0.05)
        load = 5.0 * p.force * np.where(on, np.sin(np.pi * np.clip(frac / 0.6, 0, 1)) ** 2, 0.0)
        load = np.where(frac <= 0.6, load, 0.0)
        ux, uy = np.cos(dirs[idx]), np.sin(dirs[idx])
        slide = 3.0 * (frac - 0.3)
        parts.append(Contacts.make(
            len(t), p.cx + base[0] + offs[idx, 0] + ux * slide,
            p.cy + base[1] + offs[idx, 1] + uy * slide, 3.5 * p.size, load,
            1.0 * ux * load / 5.0, 1.0 * uy * load / 5.0))
    return Contacts.join(parts)


def idle(t: np.ndarray, dur: float, p: TrialParams) -> Contacts:
    """No contact."""
    z = np.zeros((len(t), 0))
    return Contacts(z, z, z, z, z, z, z)


@dataclass(frozen=True)
class GestureModel:
    """A gesture's name, the definition shown to participants, and its contact pattern."""

    name: str
    definition: str
    movement: str  # transversal | convergent | divergent | static
    render: Callable[[np.ndarray, float, TrialParams], Contacts]


GESTURES: dict[str, GestureModel] = {g.name: g for g in (
    GestureModel("Poke", "Press briefly with one fingertip.", "static", poke),
    GestureModel("Wide Pinch", "Place two fingers far apart and bring them together.",
                 "convergent", wide_pinch),
    GestureModel("Heavy Pat", "Pat firmly with the flat of the hand, a few times.",
                 "static", heavy_pat),
    GestureModel("Twist", "Press with a finger pad and turn it back and forth.",
                 "static", twist),
    GestureModel("Back & Forth Rub", "Slide a fingertip back and forth along a line.",
                 "transversal", back_forth_rub),
    GestureModel("Isometric Rub", "Press a fingertip and push it back and forth without sliding.",
                 "static", isometric_rub),
    GestureModel("Circular Stroke", "Stroke a fingertip round in a circle.",
                 "transversal", circular_stroke),
    GestureModel("Constant Touch", "Rest the hand on the sensor with steady pressure.",
                 "static", constant_touch),
    GestureModel("Tickle", "Flick several fingertips lightly and quickly over the surface.",
                 "transversal", tickle),
)}
IDLE_MODEL = GestureModel(IDLE, "No contact.", "static", idle)
_LOOKUP = {name.lower(): name for name in (*GESTURE_NAMES, IDLE)}


def canonical_gesture(name: str) -> str:
    """The registry spelling of ``name`` (case-insensitive; 'idle' allowed); ValueError if
    unknown."""
    key = " ".join(str(name).split()).lower()
    if key not in _LOOKUP:
        raise ValueError(f"unknown gesture {name!r} (known: {', '.join(GESTURE_NAMES)}, idle)")
    return _LOOKUP[key]


def gesture_model(name: str) -> GestureModel:
    """The model for ``name`` (case-insensitive, 'idle' included)."""
    canon = canonical_gesture(name)
    return IDLE_MODEL if canon == IDLE else GESTURES[canon]
