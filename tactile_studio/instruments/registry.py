"""Finding instrument plugins: the ``tactile_studio.stages`` and ``tactile_studio.forces``
entry-point groups plus in-process registration, one
:class:`~tactile_studio.registry.Registry` each (as devices and models are found)."""

from __future__ import annotations

from typing import Any

from tactile_studio.instruments.contract import ForcePlugin, StagePlugin
from tactile_studio.registry import Registry, subclass_of

STAGE_GROUP = "tactile_studio.stages"
FORCE_GROUP = "tactile_studio.forces"
STAGES: Registry[type[StagePlugin]] = Registry(STAGE_GROUP, "stage", subclass_of(StagePlugin))
FORCES: Registry[type[ForcePlugin]] = Registry(FORCE_GROUP, "force reference",
                                               subclass_of(ForcePlugin))
_REGISTRIES = {STAGE_GROUP: STAGES, FORCE_GROUP: FORCES}


def available(group: str) -> dict[str, type | Exception]:
    """Every plugin registered in ``group`` by name; a broken one maps to its error."""
    return dict(sorted(_REGISTRIES[group].all().items()))


def register_stage(cls: type[StagePlugin], *, replace: bool = False) -> type[StagePlugin]:
    """Make the stage class ``cls`` available as ``cls.name`` in this process."""
    return STAGES.register(cls.name, cls, replace=replace)


def register_force(cls: type[ForcePlugin], *, replace: bool = False) -> type[ForcePlugin]:
    """Make the force-reference class ``cls`` available as ``cls.name`` in this process."""
    return FORCES.register(cls.name, cls, replace=replace)


def create_stage(name: str, settings: dict[str, Any] | None = None) -> StagePlugin:
    """Instantiate a stage plugin with validated settings (SettingsError on bad values)."""
    return STAGES.get(name)(**(settings or {}))


def create_force(name: str, settings: dict[str, Any] | None = None) -> ForcePlugin:
    """Instantiate a force-reference plugin with validated settings."""
    return FORCES.get(name)(**(settings or {}))
