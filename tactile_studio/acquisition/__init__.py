"""Acquisition, Qt-free: device → engine → sinks, one seam for every place that acquires.

- :mod:`tactile_studio.acquisition.live_acquisition`: :class:`LiveAcquisition`, device +
  engine + sinks with one start order, auto-stop and events (the main window, ``record``,
  ``collect`` and the collection console all use it; ui's only way to acquisition, an
  import-linter contract); the stream it hands out (``session.engine``) is held by the
  :class:`~tactile_studio.devices.frame_stream.LiveStream` protocol;
- :mod:`tactile_studio.acquisition.open_stream`: :func:`open_stream`, the one
  constructor of a device's stream (the engine; an import contract and a test keep it so);
- :mod:`tactile_studio.acquisition.file_sink`: the one way a recording's file is opened
  and closed;
- :mod:`tactile_studio.acquisition.sinks`: the :class:`Sink` protocol (setup, event,
  close; frames pulled from the engine: the HDF5 recorder, outlets, marker inlets, LSL
  publishing) and the stop order;
- :mod:`tactile_studio.acquisition.outcome`: how a recording ended;
- :mod:`tactile_studio.acquisition.status`: :class:`LiveStatus` and :func:`format_malformed`;
- :mod:`tactile_studio.acquisition.stream_health` and ``marker_recording``: a silent
  device and other programs' LSL markers while recording.
"""

from __future__ import annotations

from tactile_studio.acquisition.live_acquisition import LiveAcquisition
from tactile_studio.acquisition.open_stream import open_stream
from tactile_studio.acquisition.status import LiveStatus, format_malformed

__all__ = ["LiveAcquisition", "LiveStatus", "format_malformed", "open_stream"]
