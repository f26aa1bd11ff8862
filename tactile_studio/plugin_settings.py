"""One entry of a plugin's settings schema: devices, stages and force references share it.

A schema is data (name, kind, default, help, choices, range), so the CLI's ``--set`` and
the GUI's forms are built from it and every value is checked the same way. ``parse`` is the
one validation point for every plugin kind: a float setting must be a finite number (NaN
slips past every range check and ±inf is never a useful rate, noise or speed), so a new
plugin gets that for free.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from tactile_studio.errors import SettingsError
from tactile_studio.sensor.taxels import taxel_token

# "taxel": a name ("C3") or an index ("14"), resolved by the device on its own layout
SETTING_KINDS = {"int": int, "float": float, "str": str, "bool": bool, "choice": str, "path": str,
                 "taxel": taxel_token}


@dataclass(frozen=True)
class Setting:
    """One entry of a plugin's settings schema."""

    name: str
    kind: str  # int | float | str | bool | choice | path | taxel
    default: Any
    help: str = ""
    choices: tuple[str, ...] = ()
    minimum: float | None = None
    maximum: float | None = None
    # how a form shows it to a person: words and a unit ("Noise", "counts rms"); the
    # name stays what --set and the files use. ``advanced``: a form folds it away
    label: str = ""
    unit: str = ""
    advanced: bool = False

    @property
    def title(self) -> str:
        """The form's row label: ``label (unit)``, else the name."""
        text = self.label or self.name
        return f"{text} ({self.unit})" if self.unit else text

    def parse(self, value: Any, device: str, kind: str = "device") -> Any:
        """Convert a value (possibly the text of ``--set key=value``) and check it."""
        where = f"{kind} {device}: setting {self.name}"
        if value is None:
            return None
        try:
            if self.kind == "bool":
                if isinstance(value, str):
                    low = value.strip().lower()
                    if low not in {"1", "0", "true", "false", "yes", "no", "on", "off"}:
                        raise ValueError(value)
                    value = low in {"1", "true", "yes", "on"}
                else:
                    value = bool(value)
            else:
                value = SETTING_KINDS[self.kind](value)
        except (TypeError, ValueError, OverflowError):
            raise SettingsError(f"{where}: {value!r} is not a valid {self.kind}") from None
        if self.kind == "float" and not math.isfinite(value):
            raise SettingsError(f"{where}: {value} is not a finite number")
        if self.kind == "choice" and value not in self.choices:
            raise SettingsError(f"{where}: {value!r} is not one of {', '.join(self.choices)}")
        if self.kind == "taxel" and isinstance(value, str):
            return value  # a name: its range is the device layout's (parse_taxel)
        if self.minimum is not None and value < self.minimum:
            raise SettingsError(f"{where}: {value} is below the minimum {self.minimum}")
        if self.maximum is not None and value > self.maximum:
            raise SettingsError(f"{where}: {value} is above the maximum {self.maximum}")
        return value

    def describe(self) -> str:
        extra = f" [{'|'.join(self.choices)}]" if self.choices else ""
        rng = ""
        if self.minimum is not None or self.maximum is not None:
            rng = f" (range {self.minimum if self.minimum is not None else ''}.."
            rng += f"{self.maximum if self.maximum is not None else ''})"
        unit = f", {self.unit}" if self.unit else ""
        return f"{self.name}={self.default!r} ({self.kind}{extra}{unit}){rng}  {self.help}"


def validate_settings(schema: tuple[Setting, ...], settings: dict[str, Any], name: str,
                      kind: str = "device") -> dict[str, Any]:
    """Defaults filled in, every value parsed and range-checked, unknown keys refused; errors
    name the plugin as ``"<kind> <name>: ..."`` (a device, a stage, a force reference)."""
    by_name = {s.name: s for s in schema}
    unknown = sorted(set(settings) - set(by_name))
    if unknown:
        raise SettingsError(f"{kind} {name}: unknown setting {unknown[0]!r} "
                            f"(known: {', '.join(by_name) or 'none'})")
    return {n: s.parse(settings.get(n, s.default), name, kind) for n, s in by_name.items()}
