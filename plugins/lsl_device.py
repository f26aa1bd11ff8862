"""Any Lab Streaming Layer stream as a device: view and record it like a sensor.

The stream is found by name / type / source_id (string streams are never taken). Its
layout comes from the ``layout`` setting, else from the metadata a Tactile Studio outlet
writes, else from its channel count (180 -> shearsense-6x6, N*N -> grid-NxN). The layout
is needed before the engine starts (it sizes the ring), so the stream is looked up when
the layout is first asked for. ``device_time`` is the LSL timestamp (clock-synchronised
to this machine); ``host_time`` is the arrival time. When the stream vanishes ``read``
raises DeviceLost; ``reopen`` looks for it again (same source_id when it has one), so the
engine records the gap and goes on when the stream returns.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from tactile_studio.devices.contract import DevicePlugin, FrameBatch, Setting, layout_setting
from tactile_studio.errors import DeviceLost, DeviceNotFound, SettingsError
from tactile_studio.sensor.channels import layout_for_channels
from tactile_studio.sensor.layout import Layout, get_layout
from tactile_studio.streams.lsl_lib import load_pylsl
from tactile_studio.streams.lsl_meta import DECODED, read_tactile_desc

REOPEN_TIMEOUT_S = 1.0
READ_WAIT_S = 0.1


class LslDevice(DevicePlugin):
    """An LSL inlet delivering frames to the acquisition engine."""

    name: ClassVar[str] = "lsl"
    description: ClassVar[str] = (
        "A Lab Streaming Layer stream (e.g. another Tactile Studio's raw outlet, or any "
        "tactile grid): layout from its metadata or channel count")
    settings_schema: ClassVar[tuple[Setting, ...]] = (
        Setting("name", "str", "", "the stream's name (empty: any)"),
        Setting("type", "str", "", "the stream's type, e.g. Tactile (empty: any)"),
        Setting("source_id", "str", "", "the stream's source_id (empty: any)"),
        Setting("layout", "str", "auto", "auto (metadata, else channel count) or a layout "
                "name, e.g. shearsense-6x6, grid-8x8"),
        Setting("timeout", "float", 2.0, "seconds to look for the stream (and to scan)",
                minimum=0.1, maximum=300.0),
    )
    supports_reconnect: ClassVar[bool] = True
    supports_discover: ClassVar[bool] = True
    discover_setting: ClassVar[str] = "name"
    discover_instant: ClassVar[bool] = False  # an LSL look-up waits ``timeout`` seconds

    @classmethod
    def discover(cls, settings: Mapping[str, Any]) -> list[tuple[str, str]]:
        """Numeric LSL streams visible now, as (name, description) for the panel's Scan."""
        pylsl = load_pylsl()
        timeout = float(settings.get("timeout", 2.0))
        found = [i for i in pylsl.resolve_streams(timeout)
                 if i.channel_format() != pylsl.cf_string]
        return sorted((i.name(), f"{i.name()} ({i.type() or 'no type'}, {i.channel_count()} "
                                 f"ch at {i.nominal_srate():g} Hz, {i.hostname()})")
                      for i in found)

    def __init__(self, **settings: Any) -> None:
        super().__init__(**settings)
        for key in ("name", "type", "source_id"):
            if "'" in self.settings[key]:
                raise SettingsError(f"device lsl: setting {key}: quotes are not allowed")
        if self.settings["layout"] != "auto":
            layout_setting(self.name, self.settings["layout"])
        self._pylsl: Any = None
        self._inlet: Any = None
        self._info: Any = None
        self._layout: Layout | None = None
        self._rate = 0.0

    # ---- finding the stream -------------------------------------------------------------
    def _wanted(self) -> str:
        s = self.settings
        parts = [f"{k}='{s[k]}'" for k in ("name", "type", "source_id") if s[k]]
        return " and ".join(parts) or "any numeric stream"

    def _find(self, timeout: float, source_id: str | None = None) -> Any:
        pylsl = self._pylsl = self._pylsl or load_pylsl()
        terms = ["channel_format!='string'"]
        if source_id:
            terms.append(f"source_id='{source_id}'")
        else:
            terms += [f"{k}='{self.settings[k]}'" for k in ("name", "type", "source_id")
                      if self.settings[k]]
        found = pylsl.resolve_bypred(" and ".join(terms), 1, timeout)
        if not found:
            raise DeviceNotFound(f"lsl: no stream with {self._wanted()} found within "
                                 f"{timeout:g} s")
        if len(found) > 1 and not source_id and not any(
                self.settings[k] for k in ("name", "type", "source_id")):
            names = ", ".join(sorted({f.name() for f in found}))
            raise DeviceNotFound(f"lsl: several streams found ({names}); choose one with "
                                 "--set name=NAME")
        return found[0]

    def _connect(self, info: Any, timeout: float) -> Any:
        """An inlet on ``info`` (recover off: a vanished stream must raise, not hang)."""
        pylsl = self._pylsl
        inlet = pylsl.StreamInlet(info, max_buflen=360, recover=False,
                                  processing_flags=pylsl.proc_clocksync)
        try:
            full = inlet.info(timeout)
        except Exception as exc:  # pylsl TimeoutError / LostError
            raise DeviceNotFound(f"lsl: stream '{info.name()}' did not answer ({exc})") from None
        return inlet, full

    def _choose_layout(self, full: Any) -> Layout:
        stream = f"lsl: stream '{full.name()}'"
        n = full.channel_count()
        if self.settings["layout"] != "auto":
            lay = layout_setting(self.name, self.settings["layout"])
            if lay.n_channels != n:
                raise SettingsError(f"{stream} has {n} channels, layout {lay.name} needs "
                                    f"{lay.n_channels}")
            return lay
        ours = read_tactile_desc(full)
        if ours.get("content") == DECODED:
            raise SettingsError(f"{stream} carries decoded stresses, not raw counts; record "
                                "its raw stream instead")
        if ours.get("layout"):
            try:
                lay = get_layout(ours["layout"])
            except Exception:
                lay = None
            if lay is not None and lay.n_channels == n:
                return lay
        lay = layout_for_channels(n)
        if lay is None:
            raise SettingsError(f"{stream} has {n} channels, which matches no layout (set "
                                "layout=NAME, e.g. layout=grid-4x8)")
        return lay

    def _resolve(self) -> None:
        info = self._find(self.settings["timeout"])
        inlet, full = self._connect(info, self.settings["timeout"])
        self._layout = self._choose_layout(full)
        rate = float(full.nominal_srate())
        if rate <= 0:
            raise SettingsError(f"lsl: stream '{full.name()}' has an irregular rate; only "
                                "regularly sampled streams can be recorded")
        self._inlet, self._info, self._rate = inlet, full, rate

    # ---- contract --------------------------------------------------------------------
    @property
    def layout(self) -> Layout:
        if self._layout is None:
            self._resolve()
        assert self._layout is not None
        return self._layout

    @property
    def nominal_rate_hz(self) -> float:
        if self._layout is None:
            self._resolve()
        return self._rate

    def open(self) -> None:
        if self._inlet is None:
            if self._layout is None:
                self._resolve()
            else:
                self.reopen()
                return
        try:
            self._inlet.open_stream(self.settings["timeout"])
        except Exception as exc:
            self.close()
            raise DeviceNotFound(f"lsl: cannot open stream '{self._info.name()}' ({exc})") \
                from None

    def read(self, max_frames: int) -> FrameBatch:
        inlet = self._inlet
        if inlet is None:
            raise DeviceLost(f"lsl: stream '{self._info.name()}' is not open")
        try:
            data, stamps = inlet.pull_chunk(timeout=READ_WAIT_S, max_samples=max_frames,
                                            min_samples=1, as_numpy=True)
        except self._pylsl.util.LostError:
            raise DeviceLost(f"lsl: stream '{self._info.name()}' vanished") from None
        lay = self.layout
        if not len(stamps):
            return FrameBatch(raw=np.empty((0, lay.n_channels), dtype=lay.raw_dtype))
        raw = np.asarray(data).reshape(len(stamps), lay.n_channels)
        if np.issubdtype(np.dtype(lay.raw_dtype), np.integer):
            raw = np.clip(raw, 0, lay.raw_max)
        return FrameBatch(raw=raw.astype(lay.raw_dtype, copy=False),
                          device_time=np.asarray(stamps, dtype=np.float64))

    def close(self) -> None:
        inlet, self._inlet = self._inlet, None
        if inlet is not None:
            try:
                inlet.close_stream()
            except Exception:
                pass

    def reopen(self) -> None:
        """Look for the stream again (by its source_id when it has one)."""
        self.close()
        old = self._info
        info = self._find(REOPEN_TIMEOUT_S, source_id=old.source_id() or None)
        inlet, full = self._connect(info, REOPEN_TIMEOUT_S)
        if full.channel_count() != self.layout.n_channels:
            raise DeviceNotFound(f"lsl: stream '{full.name()}' came back with "
                                 f"{full.channel_count()} channels, not {self.layout.n_channels}")
        try:
            inlet.open_stream(REOPEN_TIMEOUT_S)
        except Exception as exc:
            raise DeviceNotFound(f"lsl: cannot reopen stream '{full.name()}' ({exc})") from None
        self._inlet, self._info = inlet, full

    def info(self) -> dict[str, Any]:
        out = super().info()
        full = self._info
        if full is not None:
            out["stream"] = {"name": full.name(), "type": full.type(),
                             "source_id": full.source_id(), "uid": full.uid(),
                             "hostname": full.hostname(), "channels": full.channel_count(),
                             "nominal_srate": full.nominal_srate()}
            ours = read_tactile_desc(full)
            if ours.get("sensor_id"):
                out["sensor_id"] = ours["sensor_id"]
        return out
