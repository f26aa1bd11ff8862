"""Building a run from what a user typed (the wizard's and the CLI's shared front half)."""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

from tactile_studio.characterise.plan import Plan
from tactile_studio.devices.contract import DevicePlugin
from tactile_studio.devices.registry import available_plugins, create_device, parse_set_options
from tactile_studio.errors import UserError
from tactile_studio.instruments.contract import ForcePlugin, StagePlugin
from tactile_studio.instruments.registry import (
    FORCE_GROUP,
    STAGE_GROUP,
    available,
    create_force,
    create_stage,
)
from tactile_studio.sensor.characterise import parse_taxels


@dataclass
class Prepared:
    device: DevicePlugin
    stage: StagePlugin
    force: ForcePlugin
    plan: Plan
    taxels: list[int]


def plugin_names() -> dict[str, list[str]]:
    """Loadable device, stage and force plugin names, for choosers."""
    def ok(found: dict) -> list[str]:
        return [n for n, c in found.items() if not isinstance(c, Exception)]
    return {"device": ok(available_plugins()), "stage": ok(available(STAGE_GROUP)),
            "force": ok(available(FORCE_GROUP))}


def settings_from_text(text: str) -> dict[str, str]:
    """``"speed=0 gesture=idle"`` (spaces, commas or new lines between) -> dict."""
    return parse_set_options([p for p in text.replace(",", " ").split() if p])


def plan_fields() -> list[tuple[str, str]]:
    """(name, default as text) of every plan parameter, in order."""
    plan = Plan()
    out = []
    for f in fields(Plan):
        v = getattr(plan, f.name)
        out.append((f.name, ",".join(v) if isinstance(v, tuple) else str(v)))
    return out


def prepare(device: str, device_settings: str, stage: str, stage_settings: str, force: str,
            force_settings: str, taxels: str, params: dict[str, Any]) -> Prepared:
    """Validate everything up front (one-line UserErrors), before anything moves."""
    plan = Plan.with_overrides(params)
    dev = create_device(device, settings_from_text(device_settings))
    try:
        numbers = parse_taxels(dev.layout, taxels)
    except ValueError as exc:
        raise UserError(f"taxels: {exc}") from None
    return Prepared(dev, create_stage(stage, settings_from_text(stage_settings)),
                    create_force(force, settings_from_text(force_settings)), plan, numbers)
