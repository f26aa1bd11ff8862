"""The shear paper's gesture metrics of a window, computed inside a network.

The random forest's strongest features for unseen people are the gesture metrics of
``sensor/gesture_metrics.py`` (movement type, spread change, contact area, ...). They are
defined in physical units with thresholds relative to the touch's own peak, which a
network seeing z-scored windows cannot reproduce with its affine layers: a cell is "in
contact" above 10% of the window's peak *load*, whose zero the z-scoring moved. So this
module holds the fold's normalisation (``input_mean``/``input_std`` buffers, saved with
the weights; :meth:`set_input_norm` after building) and undoes it first. It is written in
tensor operations only, so the metrics export to ONNX and stream live with the model.
``tests/test_gesture_features.py`` checks it against the numpy definition.
"""

from __future__ import annotations

import math

import torch
from torch import nn

from tactile_studio.sensor.gesture_metrics import (
    MOVEMENT_TYPES,
    SPREAD_MIN_PITCH,
    SPREAD_THRESHOLD,
    TRAVEL_THRESHOLD,
)


def _gradient(f: torch.Tensor, dim: int, spacing: float) -> torch.Tensor:
    """``numpy.gradient`` along ``dim`` (central inside, one-sided at the edges)."""
    n = f.shape[dim]
    if n < 2:
        return torch.zeros_like(f)
    first = f.narrow(dim, 1, 1) - f.narrow(dim, 0, 1)
    last = f.narrow(dim, n - 1, 1) - f.narrow(dim, n - 2, 1)
    if n == 2:
        return torch.cat([first, last], dim) / spacing
    inner = (f.narrow(dim, 2, n - 2) - f.narrow(dim, 0, n - 2)) / 2
    return torch.cat([first, inner, last], dim) / spacing


def fourier_basis(frames: int) -> tuple[torch.Tensor, torch.Tensor]:
    """(frames, frames // 2) cosines and sines of the non-DC DFT frequencies: a fixed
    matrix, so spectra export to ONNX as two matrix products."""
    freqs = torch.arange(1, frames // 2 + 1, dtype=torch.float32)
    t = torch.arange(frames, dtype=torch.float32)
    angle = 2 * math.pi * t[:, None] * freqs[None, :] / frames
    return torch.cos(angle), torch.sin(angle)


def metric_names(channels: int) -> list[str]:
    """Names of :meth:`GestureFeatures.metrics`' columns for 1 (normal or pressure),
    2 (shear x/y) or 3 (normal + shear) channels: ``trial_features``' gesture names."""
    names = ["mean_normal"] if channels != 2 else []
    names += ["mean_abs_shear"] if channels >= 2 else []
    names += ["contact_area", "dominant_hz", "centroid_speed", "spread_change"]
    names += ["divergence", "curl", "coherence"] if channels >= 2 else []
    return names + [f"movement_{m}" for m in MOVEMENT_TYPES]


class GestureFeatures(nn.Module):
    """Window (B, C, T, R, X), z-scored -> its gesture metrics, sign-log compressed and
    batch-normalised. ``window_s``: the seconds a window spans (for per-second speeds and
    the 3 pitch/s travel threshold); the cell pitch (taxel pitches per grid cell) and the
    input normalisation come with :meth:`set_input_norm`."""

    def __init__(self, channels: int, frames: int, window_s: float = 2.0) -> None:
        super().__init__()
        self.channels, self.frames = channels, frames
        self.rate = frames / window_s
        self.names = metric_names(channels)
        self.out_features = len(self.names)
        self.register_buffer("input_mean", torch.zeros(channels))
        self.register_buffer("input_std", torch.ones(channels))
        self.register_buffer("cell_pitch", torch.ones(()))
        cos, sin = fourier_basis(frames)
        self.register_buffer("cos", cos, persistent=False)
        self.register_buffer("sin", sin, persistent=False)
        self.norm = nn.BatchNorm1d(self.out_features)

    def set_input_norm(self, mean, std, cell_pitch: float = 1.0) -> None:
        """The per-channel mean and std the model's inputs were z-scored with, and the
        physical taxel pitches per grid cell (0.5 on the virtual grid)."""
        with torch.no_grad():
            self.input_mean.copy_(torch.as_tensor(mean, dtype=torch.float32))
            self.input_std.copy_(torch.as_tensor(std, dtype=torch.float32))
            self.cell_pitch.fill_(float(cell_pitch))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.norm(self.raw(x))

    def raw(self, x: torch.Tensor) -> torch.Tensor:
        """The compressed metrics before the batch norm (no learned weight in them)."""
        m = self.metrics(x)
        return torch.sign(m) * torch.log1p(m.abs())

    def metrics(self, x: torch.Tensor) -> torch.Tensor:
        """(B, out_features) metrics in physical units, as ``gesture_metrics`` defines
        them (float32; the movement type one-hot last)."""
        shape = (1, self.channels, 1, 1, 1)
        x = x * self.input_std.view(shape) + self.input_mean.view(shape)
        b, c, t, r, s = x.shape
        normal = x[:, 0] if c != 2 else None
        sx, sy = (x[:, -2], x[:, -1]) if c >= 2 else (None, None)
        mag = torch.sqrt(sx ** 2 + sy ** 2) if sx is not None else None
        load = torch.relu(normal) if normal is not None else mag
        peak = load.amax((1, 2, 3), keepdim=True)
        contact = (load > torch.clamp(0.1 * peak, min=1e-9)).to(x.dtype)
        weight = load * contact
        total = weight.sum((2, 3))  # (B, T)
        tmax = total.amax(1, keepdim=True)
        active = ((total > 0.25 * tmax) & (tmax > 0)).to(x.dtype)
        n_contact = torch.clamp(contact.sum((1, 2, 3)), min=1.0)
        n_active = active.sum(1)
        out = []
        if normal is not None:
            out.append((normal * contact).sum((1, 2, 3)) / n_contact)
        if mag is not None:
            mean_shear = (mag * contact).sum((1, 2, 3)) / n_contact
            out.append(mean_shear)
        out.append((contact.mean((2, 3)) * active).sum(1) / torch.clamp(n_active, min=1.0))
        out.append(self._dominant_hz(total))
        speed, spread, spread_abs = self._movement(weight, total, active, n_active)
        out += [speed, spread]
        if mag is not None:
            out += self._shear_field(sx, sy, weight, contact, n_contact, mean_shear)
        converge = (spread < -SPREAD_THRESHOLD) & (spread_abs >= SPREAD_MIN_PITCH)
        diverge = (spread > SPREAD_THRESHOLD) & (spread_abs >= SPREAD_MIN_PITCH)
        travel = ~converge & ~diverge & (speed > TRAVEL_THRESHOLD)
        static = ~converge & ~diverge & ~travel
        kinds = {"static": static, "transversal": travel, "convergent": converge,
                 "divergent": diverge}
        out += [kinds[m].to(x.dtype) for m in MOVEMENT_TYPES]
        return torch.stack(out, dim=1)

    def _dominant_hz(self, total: torch.Tensor) -> torch.Tensor:
        if self.frames < 4:
            return torch.zeros_like(total[:, 0])
        centred = total - total.mean(1, keepdim=True)
        power = (centred @ self.cos) ** 2 + (centred @ self.sin) ** 2
        hz = (power.argmax(1) + 1).to(total.dtype) * (self.rate / self.frames)
        return torch.where(power.sum(1) > 1e-12, hz, torch.zeros_like(hz))

    def _movement(self, weight, total, active, n_active):
        """Centroid speed (pitch/s), spread change and its size in pitches over the
        active frames (all 0 with fewer than 3 active frames)."""
        b, t, r, s = weight.shape
        yy = torch.arange(r, dtype=weight.dtype).view(1, 1, r, 1) * self.cell_pitch
        xx = torch.arange(s, dtype=weight.dtype).view(1, 1, 1, s) * self.cell_pitch
        wt = torch.clamp(total, min=1e-12)
        cy = (weight * yy).sum((2, 3)) / wt
        cx = (weight * xx).sum((2, 3)) / wt
        gyr = torch.sqrt(torch.clamp(
            (weight * ((yy - cy[..., None, None]) ** 2 + (xx - cx[..., None, None]) ** 2))
            .sum((2, 3)) / wt, min=0.0))
        idx = torch.arange(t, dtype=weight.dtype).view(1, t)
        on = active > 0
        first = torch.where(on, idx, torch.full_like(idx.expand(b, t), float(t))).amin(1)
        last = torch.where(on, idx, torch.full_like(idx.expand(b, t), -1.0)).amax(1)
        duration = torch.clamp(last - first, min=1.0) / self.rate
        both = active[:, 1:] * active[:, :-1]
        step = torch.sqrt((cx[:, 1:] - cx[:, :-1]) ** 2 + (cy[:, 1:] - cy[:, :-1]) ** 2)
        speed = (step * both).sum(1) / duration
        third = torch.clamp(torch.floor(n_active / 3), min=1.0)
        rank = torch.cumsum(active, 1)
        head = active * (rank <= third[:, None]).to(weight.dtype)
        tail = active * (rank > (n_active - third)[:, None]).to(weight.dtype)
        g_first = (gyr * head).sum(1) / third
        g_last = (gyr * tail).sum(1) / third
        big = torch.clamp(torch.maximum(g_first, g_last), min=1e-9)
        spread = (g_last - g_first) / big
        enough = (n_active >= 3).to(weight.dtype)
        return speed * enough, spread * enough, (g_last - g_first).abs() * enough

    def _shear_field(self, sx, sy, weight, contact, n_contact, mean_shear):
        """Contact-weighted divergence and curl per |shear|, and coherence."""
        p = self.cell_pitch
        div = _gradient(sx, 3, p) + _gradient(sy, 2, p)
        curl = _gradient(sy, 3, p) - _gradient(sx, 2, p)
        wsum = weight.sum((1, 2, 3))
        scale = torch.clamp(mean_shear, min=1e-9)
        denom = torch.clamp(wsum, min=1e-12) * scale
        has = (wsum > 0).to(sx.dtype)
        vx = (sx * contact).sum((1, 2, 3)) / n_contact
        vy = (sy * contact).sum((1, 2, 3)) / n_contact
        return [(div * weight).sum((1, 2, 3)) / denom * has,
                (curl * weight).sum((1, 2, 3)) / denom * has,
                torch.sqrt(vx ** 2 + vy ** 2) / scale]
