"""One way to find extensions: an entry-point group plus in-process registration.

Devices (``tactile_studio.devices``), stages and force references (``tactile_studio.stages``,
``tactile_studio.forces``) and models (``tactile_studio.models``) are each one
:class:`Registry`. Names come from the group's entry points (listed without importing
anything, read once per process) and from :meth:`Registry.register` (a notebook, a script,
a test). An entry's module is imported the first time that entry is asked for, and the
result is kept: a broken third-party package costs one import attempt, is reported by name
(its exception stands in for it) and never hides the others.
"""

from __future__ import annotations

from collections.abc import Callable
from importlib.metadata import EntryPoint, entry_points
from typing import Generic, TypeVar

from tactile_studio.errors import UserError

T = TypeVar("T")


class Registry(Generic[T]):
    """The ``group``'s entries by name: lazy, cached, plus in-process registration.

    ``accept(name, obj, origin)`` returns ``obj`` when it is a valid ``kind`` entry, or
    raises (``TypeError``/``ValueError``) saying why not; ``origin`` names where the
    object came from (the entry point's ``module:attr``) for that message."""

    def __init__(self, group: str, kind: str, accept: Callable[[str, object, str], T]) -> None:
        self.group = group
        self.kind = kind
        self._accept = accept
        self._registered: dict[str, T] = {}
        self._loaded: dict[str, T | Exception] = {}
        self._entry_points: dict[str, EntryPoint] | None = None

    def entry_points(self) -> dict[str, EntryPoint]:
        """The group's entry points by name in declaration order (the first of a name wins,
        as Python imports the first one on the path)."""
        if self._entry_points is None:
            found: dict[str, EntryPoint] = {}
            for ep in entry_points(group=self.group):
                found.setdefault(ep.name, ep)
            self._entry_points = found
        return self._entry_points

    def names(self) -> list[str]:
        """Every name: entry points first, in declaration order, then registered ones."""
        eps = self.entry_points()
        return [*eps, *(n for n in self._registered if n not in eps)]

    def register(self, name: str, obj: T, *, replace: bool = False) -> T:
        """Make ``obj`` available as ``name`` in this process (checked as an entry point
        would be). A name already taken is an error unless ``replace``."""
        obj = self._accept(name, obj, f"{obj!r}")
        if not replace and name in self.names() and self._registered.get(name) is not obj:
            raise ValueError(f"a {self.kind} named {name!r} is already registered")
        self._registered[name] = obj
        return obj

    def unregister(self, name: str) -> None:
        """Forget an entry made with :meth:`register` (tests clean up with it)."""
        self._registered.pop(name, None)

    def load(self, name: str) -> T | Exception:
        """The entry ``name`` (KeyError if there is none), or the exception that keeps it
        from loading; an entry point's module is imported once."""
        if name in self._registered:
            return self._registered[name]
        if name not in self._loaded:
            ep = self.entry_points()[name]
            try:
                obj = ep.load()
            except Exception as exc:  # a broken third-party package must not break the app
                self._loaded[name] = exc
            else:
                try:
                    self._loaded[name] = self._accept(name, obj, ep.value)
                except (TypeError, ValueError) as exc:
                    self._loaded[name] = exc
        return self._loaded[name]

    def all(self) -> dict[str, T | Exception]:
        """Every entry by name, loaded; a broken one maps to its error."""
        return {name: self.load(name) for name in self.names()}

    def get(self, name: str) -> T:
        """The entry ``name``; a one-line UserError when it is unknown or cannot load."""
        names = self.names()
        if name not in names:
            raise UserError(f"unknown {self.kind} {name!r} "
                            f"(available: {', '.join(names) or 'none'})")
        obj = self.load(name)
        if isinstance(obj, Exception):
            raise UserError(f"{self.kind} plugin {name!r} failed to load: {obj}")
        return obj


def subclass_of(base: type) -> Callable[[str, object, str], type]:
    """An ``accept`` for plugin classes: a subclass of ``base``."""

    def accept(name: str, obj: object, origin: str) -> type:
        if not (isinstance(obj, type) and issubclass(obj, base)):
            raise TypeError(f"{origin} is not a {base.__name__} subclass")
        return obj

    return accept
