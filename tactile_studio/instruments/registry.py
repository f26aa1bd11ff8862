"""Finding instrument plugins through the ``tactile_studio.stages`` and
``tactile_studio.forces`` entry-point groups (as devices are found)."""

from __future__ import annotations

from importlib.metadata import entry_points
from typing import Any

from tactile_studio.errors import UserError
from tactile_studio.instruments.contract import ForcePlugin, StagePlugin

STAGE_GROUP = "tactile_studio.stages"
FORCE_GROUP = "tactile_studio.forces"
_BASES = {STAGE_GROUP: StagePlugin, FORCE_GROUP: ForcePlugin}
_KIND = {STAGE_GROUP: "stage", FORCE_GROUP: "force reference"}


def available(group: str) -> dict[str, type | Exception]:
    """Every plugin registered in ``group`` by name; a broken one maps to its error."""
    found: dict[str, type | Exception] = {}
    for ep in sorted(entry_points(group=group), key=lambda e: e.name):
        try:
            cls = ep.load()
        except Exception as exc:  # a broken third-party plugin must not break the app
            found[ep.name] = exc
            continue
        if not (isinstance(cls, type) and issubclass(cls, _BASES[group])):
            found[ep.name] = TypeError(f"{ep.value} is not a {_BASES[group].__name__} subclass")
            continue
        found[ep.name] = cls
    return found


def _create(group: str, name: str, settings: dict[str, Any] | None) -> Any:
    plugins = available(group)
    if name not in plugins:
        raise UserError(f"unknown {_KIND[group]} {name!r} "
                        f"(available: {', '.join(plugins) or 'none'})")
    cls = plugins[name]
    if isinstance(cls, Exception):
        raise UserError(f"{_KIND[group]} plugin {name!r} failed to load: {cls}")
    return cls(**(settings or {}))


def create_stage(name: str, settings: dict[str, Any] | None = None) -> StagePlugin:
    """Instantiate a stage plugin with validated settings (SettingsError on bad values)."""
    return _create(STAGE_GROUP, name, settings)


def create_force(name: str, settings: dict[str, Any] | None = None) -> ForcePlugin:
    """Instantiate a force-reference plugin with validated settings."""
    return _create(FORCE_GROUP, name, settings)
