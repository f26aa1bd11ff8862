"""The live screen's views, Qt-free: one import path for the widgets, CLI and tests.

The code lives in focused modules of this package; their public names are exported here
(``from tactile_studio.live import LiveView, History, ...``):

- :mod:`tactile_studio.live.view`: :class:`LiveView` (newest decoded frame, cell
  readout, strip-chart history) and its data (:class:`LiveFrame`, :class:`CellReadout`,
  :class:`History`, :func:`parse_taxel_name`);
- the acquisition itself (device, engine, recording, LSL) is
  :mod:`tactile_studio.acquisition` (:class:`LiveAcquisition`, the widgets' only way
  to it); the views hold the stream it hands out by the
  :class:`~tactile_studio.devices.frame_stream.LiveStream` protocol;
- :mod:`tactile_studio.live.meters`: :class:`RateMeter` (display fps) and
  :class:`LatencyMeter` (device-to-paint latency);
- :mod:`tactile_studio.live.discovery`: :func:`run_discovery`, the device panel's "Scan".
"""

from __future__ import annotations

from tactile_studio.live.discovery import (
    discover_is_instant,
    discover_setting,
    discover_settings,
    run_discovery,
)
from tactile_studio.live.meters import LatencyMeter, RateMeter
from tactile_studio.live.view import (
    QUANTITIES,
    QUANTITY_LABELS,
    CellReadout,
    History,
    LiveFrame,
    LiveView,
    parse_taxel_name,
)

__all__ = [
    "QUANTITIES", "QUANTITY_LABELS", "CellReadout", "History",
    "LatencyMeter", "LiveFrame", "LiveView", "RateMeter", "discover_is_instant",
    "discover_setting", "discover_settings", "parse_taxel_name", "run_discovery",
]
