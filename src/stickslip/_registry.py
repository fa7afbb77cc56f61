"""Discovery of plugins through entry-point groups: models (`stickslip.models`) and trace
kinds (`stickslip.trace_kinds`).

Built-in models and trace kinds are registered the same way a third-party package registers
its own (see `pyproject.toml`). Discovery is cached; `refresh_models()` rescans. A plugin
that fails to import, is not a subclass of its group's base class, or repeats a name already
taken gives a warning naming it and is skipped: one broken plugin never breaks the package.
"""

from __future__ import annotations

import warnings
from importlib.metadata import EntryPoint, entry_points
from typing import TYPE_CHECKING, Any

from ._errors import PluginError

if TYPE_CHECKING:
    from ._model import FrictionModel

ENTRY_POINT_GROUP = "stickslip.models"
TRACE_KIND_GROUP = "stickslip.trace_kinds"


class PluginWarning(UserWarning):
    """A plugin (a model or a trace kind) could not be loaded or clashes with another."""


_REGISTRIES: list = []  # every group's registry (`refresh_models` rescans them all)


class Registry:
    """The classes of one entry-point `group`, subclasses of the class `base()` returns
    (imported when first needed), called `noun` in messages ("model", "trace kind")."""

    def __init__(self, group: str, base, noun: str, public: str):
        self.group, self.base, self.noun, self.public = group, base, noun, public
        self.cache: dict[str, type] | None = None
        self.runtime: dict[str, type] = {}
        self.named_cache: dict[str, type | None] = {}
        _REGISTRIES.append(self)

    def load(self, entries: list[EntryPoint]) -> dict[str, type]:
        """The classes of `entries` by name; a broken, foreign or repeated one is a warning."""
        base, found = self.base(), {}
        for ep in sorted(entries, key=lambda e: (e.name, e.value)):
            what = f"stickslip: {self.noun} plugin '{ep.name}' ({ep.value})"
            if ep.name in found:
                warnings.warn(f"{what} duplicates an earlier plugin of that name "
                              f"({found[ep.name].__module__}); ignored", PluginWarning,
                              stacklevel=4)  # fmt: skip
                continue
            try:
                obj = ep.load()
            except Exception as exc:  # a broken plugin must not break discovery
                warnings.warn(f"{what} failed to load: {type(exc).__name__}: {exc}",
                              PluginWarning, stacklevel=4)  # fmt: skip
                continue
            if not (isinstance(obj, type) and issubclass(obj, base)):
                warnings.warn(f"{what} is not a subclass of {self.public}; ignored",
                              PluginWarning, stacklevel=4)  # fmt: skip
                continue
            found[ep.name] = obj
        return found

    def discover(self) -> dict[str, type]:
        if self.cache is None:
            self.cache = self.load(list(entry_points(group=self.group)))
        return self.cache

    def named(self, name: str) -> type | None:
        """The plugin `name` alone, loading only its entry points (importing every plugin
        costs a second or more); `None` if none loads under that name."""
        if self.cache is not None:
            return self.cache.get(name) or self.runtime.get(name)
        if name not in self.named_cache:
            entries = [ep for ep in entry_points(group=self.group) if ep.name == name]
            self.named_cache[name] = self.load(entries).get(name) if entries else None
        return self.named_cache[name] or self.runtime.get(name)

    def refresh(self) -> None:
        self.cache = None
        self.named_cache.clear()

    def all(self) -> dict[str, type]:
        """Entry-point plugins first, then those registered at run time, sorted by name."""
        found = dict(self.discover())
        for name, cls in self.runtime.items():
            found.setdefault(name, cls)
        return dict(sorted(found.items()))

    def register(self, owner: str, name: str, cls: Any) -> None:
        if not (isinstance(cls, type) and issubclass(cls, self.base())):
            raise TypeError(f"{owner}: {cls!r} is not a subclass of {self.public}")
        if name in self.discover() and self.discover()[name] is not cls:
            raise PluginError(f"{owner}: the name '{name}' is taken by an installed plugin")
        self.runtime[name] = cls

    def get(self, name: Any) -> type:
        if isinstance(name, type):
            if issubclass(name, self.base()):
                return name
            raise PluginError(f"{name!r} is not a subclass of {self.public}")
        found = self.named(name)
        if found is not None:
            return found
        known = self.all()
        if name in known:
            return known[name]
        listed = ", ".join(known) or "none installed"
        raise PluginError(f"unknown {self.noun} '{name}' (known {self.noun}s: {listed})")

    def name_of(self, cls: type) -> str:
        for name, registered in self.all().items():
            if registered is cls:
                return name
        return cls.__name__


def _friction_model():
    from ._model import FrictionModel

    return FrictionModel


MODELS = Registry(ENTRY_POINT_GROUP, _friction_model, "model", "stickslip.FrictionModel")
_runtime = MODELS.runtime


def _load(entries: list[EntryPoint]) -> dict[str, type[FrictionModel]]:
    return MODELS.load(entries)


def refresh_models() -> None:
    """Forget the cached plugin scan (models and trace kinds); the next lookup rescans the
    entry points."""
    for registry in _REGISTRIES:
        registry.refresh()


def list_models() -> dict[str, type[FrictionModel]]:
    """All available models, `{name: class}`, sorted by name.

    Entry-point plugins first, then models added with `register_model` (which may not
    shadow a plugin name).
    """
    return MODELS.all()


def register_model(name: str, cls: type[FrictionModel]) -> None:
    """Register a model class under `name` for this process (no packaging needed).

    Packages should prefer the `stickslip.models` entry point; this is for notebooks and
    scripts.
    """
    MODELS.register("register_model", name, cls)


def get_model(name: str | type[FrictionModel]) -> type[FrictionModel]:
    """The model class registered as `name` (a class is returned unchanged).

    Raises `PluginError` with the list of known names when there is no such model.
    """
    return MODELS.get(name)


def model_name(cls: type[FrictionModel]) -> str:
    """The registry name of a model class (its class name if it is not registered)."""
    return MODELS.name_of(cls)
