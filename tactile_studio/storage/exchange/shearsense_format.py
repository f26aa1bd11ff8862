"""The ShearSense CSV's fixed layout (DESIGN.md), shared by its reader and writer."""

from __future__ import annotations

N_CHANNELS = 180
N_FIELDS = N_CHANNELS + 3  # time, channels, touched, label
MAX_COUNT = 65535
HEADER = ["time (s)", *(f"Channel{i}" for i in range(N_CHANNELS)), "touched", "label"]
MALFORMED_KINDS = ("short_row", "long_row", "merged_number", "unparsable")
