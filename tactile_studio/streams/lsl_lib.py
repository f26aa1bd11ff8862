"""Loading pylsl (and its bundled liblsl) lazily, with a one-line error when it is missing."""

from __future__ import annotations

from types import ModuleType

from tactile_studio.errors import DeviceError


class LslUnavailable(DeviceError):
    """pylsl or the liblsl library it needs cannot be loaded on this machine."""


def load_pylsl() -> ModuleType:
    """The ``pylsl`` module, or LslUnavailable saying what to install."""
    try:
        import pylsl
    except (ImportError, OSError, RuntimeError) as exc:
        detail = " ".join(str(exc).split())[:160]
        raise LslUnavailable(
            f"Lab Streaming Layer is not available ({detail}); install it with "
            "`pip install pylsl` (its wheel ships liblsl)") from None
    return pylsl
