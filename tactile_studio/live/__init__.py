"""The live screen's logic, Qt-free: one import path for the widgets, CLI and tests.

The code lives in focused modules of this package; their public names are exported here
(``from tactile_studio.live import LiveView, LiveController, ...``):

- :mod:`tactile_studio.live.view`: :class:`LiveView` (newest decoded frame, cell
  readout, strip-chart history) and its data (:class:`LiveFrame`, :class:`CellReadout`,
  :class:`History`, :func:`parse_taxel_name`);
- :mod:`tactile_studio.live.session`: :class:`AcquisitionSession`, device + engine +
  optional recorder + optional LSL outlets with one start order, auto-stop and events
  (every place that acquires uses it); :mod:`tactile_studio.live.controller`:
  :class:`LiveController`, the main window's session. The session is ui's only way to
  acquisition (an import-linter contract): :class:`AcquisitionEngine`, the engine it
  hands out (``session.engine``), is re-exported here for the widgets that hold one;
- :mod:`tactile_studio.live.status`: :class:`LiveStatus` and :func:`format_malformed`;
- :mod:`tactile_studio.live.meters`: :class:`RateMeter` (display fps) and
  :class:`LatencyMeter` (device-to-paint latency);
- :mod:`tactile_studio.live.discovery`: :func:`run_discovery`, the device panel's "Scan".
"""

from __future__ import annotations

from tactile_studio.devices.engine import AcquisitionEngine
from tactile_studio.live.controller import LiveController
from tactile_studio.live.discovery import (
    discover_is_instant,
    discover_setting,
    discover_settings,
    run_discovery,
)
from tactile_studio.live.meters import LatencyMeter, RateMeter
from tactile_studio.live.session import AcquisitionSession
from tactile_studio.live.status import LiveStatus, format_malformed
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
    "QUANTITIES", "QUANTITY_LABELS", "AcquisitionEngine", "AcquisitionSession", "CellReadout",
    "History", "LatencyMeter", "LiveController", "LiveFrame", "LiveStatus", "LiveView", "RateMeter",
    "discover_is_instant", "discover_setting", "discover_settings", "format_malformed",
    "parse_taxel_name", "run_discovery",
]
