"""Finding models: the ``tactile_studio.models`` entry-point group plus ``register_model``.

Every model, built-in or third-party, is a :class:`ModelSpec` found through the entry-point
group (``name = "package.module:MODEL"`` in a package's pyproject.toml; the built-ins are
declared in this project's) or registered in-process with :func:`register_model` (for a
notebook, a script, a test). Entry points are listed without importing anything; a model's
module is imported the first time the model is asked for, so listing names stays cheap and
a broken third-party model cannot break the others (one
:class:`~tactile_studio.registry.Registry`, as devices and instruments are found).
"""

from __future__ import annotations

import re
from collections.abc import Iterator, Mapping

from tactile_studio.errors import UserError
from tactile_studio.learn.choices import BASELINES
from tactile_studio.learn.models.spec import ModelSpec, check_preset
from tactile_studio.registry import Registry

GROUP = "tactile_studio.models"
RESERVED = BASELINES  # the scikit-learn baselines' names (learn/learners/baselines.py)
NAME_RE = re.compile(r"^[a-z][a-z0-9_-]*$")


def _accept(name: str, spec: object, origin: str) -> ModelSpec:
    if not isinstance(spec, ModelSpec):
        raise TypeError(f"{origin} is a {type(spec).__name__}, not a ModelSpec")
    if spec.name != name:
        raise ValueError(f"{origin} declares the model {spec.name!r}, registered as {name!r}")
    return spec


_MODELS: Registry[ModelSpec] = Registry(GROUP, "model", _accept)


def register_model(spec: ModelSpec, *, replace: bool = False) -> ModelSpec:
    """Make ``spec`` available under ``spec.name`` in this process (``--model NAME``,
    the research workspace, sweeps). Returns ``spec``, so a module can write
    ``MODEL = register_model(ModelSpec(...))``. A name already taken is an error unless
    ``replace`` (re-running a notebook cell)."""
    if not isinstance(spec, ModelSpec):
        raise TypeError(f"register_model takes a ModelSpec, not {type(spec).__name__}")
    if not NAME_RE.match(spec.name) or spec.name in RESERVED:
        raise ValueError(f"model name {spec.name!r}: use lowercase letters, digits, - or _, "
                         f"and not {', '.join(RESERVED)}")
    return _MODELS.register(spec.name, spec, replace=replace)


def unregister_model(name: str) -> None:
    """Forget a model registered with :func:`register_model` (tests clean up with it)."""
    _MODELS.unregister(name)


def model_names() -> list[str]:
    """Every model name: entry points first, in declaration order, then registered ones."""
    return _MODELS.names()


def get_model_spec(name: str) -> ModelSpec:
    """The registered model called ``name``; a one-line UserError if there is none."""
    names = model_names()
    if name not in names:
        hint = (", ".join(names) if names else
                "none: reinstall the package (pip install -e .) to register the built-ins")
        raise UserError(f"unknown model '{name}' (available: {hint})")
    spec = _MODELS.load(name)
    if isinstance(spec, Exception):
        raise UserError(f"model '{name}' failed to load: {type(spec).__name__}: {spec}")
    return spec


class _Models(Mapping[str, ModelSpec]):
    """Read-only view of the registry by name (loads a model's module on first access)."""

    def __getitem__(self, name: str) -> ModelSpec:
        if name not in model_names():
            raise KeyError(name)
        return get_model_spec(name)

    def __iter__(self) -> Iterator[str]:
        return iter(model_names())

    def __len__(self) -> int:
        return len(model_names())

    def __contains__(self, name: object) -> bool:
        return name in model_names()

    def __repr__(self) -> str:
        return f"MODELS({', '.join(model_names())})"


MODELS: Mapping[str, ModelSpec] = _Models()


def option_help(name: str) -> dict[str, str]:
    """One line of help per architecture option of model ``name``."""
    return dict(get_model_spec(name).option_help)


def model_options(name: str, preset: str = "full") -> dict[str, object]:
    """The architecture options ``build`` accepts as overrides, with their preset values
    (for run configs and ``--set`` help). Training options are in ``TrainDefaults``."""
    return dict(get_model_spec(name).options[check_preset(preset)])
