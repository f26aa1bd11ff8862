"""What ``collect`` (without a virtual participant) pre-fills the experimenter console
with: one settings object, built and checked Qt-free by ``cli/collect.console_options``
and read by ``ui/collect/app.build_console``, so the command line and the window agree on
one list of fields instead of a dozen keyword arguments passed twice."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


@dataclass(frozen=True)
class ConsoleOptions:
    protocol: str | None = None          # a shipped protocol's name or a protocol file
    participant: str = ""
    device: str | None = None            # a device plugin's name (None: the form's own)
    device_settings: dict[str, Any] = field(default_factory=dict)  # the plugin's fields
    out_dir: str | None = None
    blocks: int | None = None
    seed: int | None = None
    condition: str = ""
    pilot: bool = False
    resume: str | None = None            # a session file to resume instead of a new one
    lsl: bool = False                    # stream on LSL once the session is open
    markers: tuple[str, ...] = ()        # LSL marker streams the recording takes in
    silence_warning_s: float | None = None  # how long the device may be silent, unsaid
    # the setup's trial check: model, top_k, threshold, personalise (``--qc-model``)
    qc: dict[str, Any] | None = None
