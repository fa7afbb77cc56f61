"""Discovery of model plugins through the entry-point group `stickslip.models`.

Built-in models are registered the same way a third-party package registers its own (see
`pyproject.toml`). Discovery is cached; `refresh_models()` rescans. A plugin that fails to
import, is not a `FrictionModel`, or repeats a name already taken gives a warning naming it
and is skipped: one broken plugin never breaks the package.
"""

from __future__ import annotations

import warnings
from importlib.metadata import EntryPoint, entry_points
from typing import TYPE_CHECKING

from ._errors import PluginError

if TYPE_CHECKING:
    from ._model import FrictionModel

ENTRY_POINT_GROUP = "stickslip.models"

_cache: dict[str, type[FrictionModel]] | None = None
_runtime: dict[str, type[FrictionModel]] = {}
_named_cache: dict[str, type[FrictionModel] | None] = {}


class PluginWarning(UserWarning):
    """A model plugin could not be loaded or clashes with another."""


def _load(entries: list[EntryPoint]) -> dict[str, type[FrictionModel]]:
    from ._model import FrictionModel

    models: dict[str, type[FrictionModel]] = {}
    for ep in sorted(entries, key=lambda e: (e.name, e.value)):
        if ep.name in models:
            warnings.warn(
                f"stickslip: model plugin '{ep.name}' ({ep.value}) duplicates an earlier "
                f"plugin of that name ({models[ep.name].__module__}); ignored",
                PluginWarning,
                stacklevel=3,
            )
            continue
        try:
            obj = ep.load()
        except Exception as exc:  # a broken plugin must not break discovery
            warnings.warn(
                f"stickslip: model plugin '{ep.name}' ({ep.value}) failed to load: "
                f"{type(exc).__name__}: {exc}",
                PluginWarning,
                stacklevel=3,
            )
            continue
        if not (isinstance(obj, type) and issubclass(obj, FrictionModel)):
            warnings.warn(
                f"stickslip: model plugin '{ep.name}' ({ep.value}) is not a subclass of "
                "stickslip.FrictionModel; ignored",
                PluginWarning,
                stacklevel=3,
            )
            continue
        models[ep.name] = obj
    return models


def _discover() -> dict[str, type[FrictionModel]]:
    global _cache
    if _cache is None:
        _cache = _load(list(entry_points(group=ENTRY_POINT_GROUP)))
    return _cache


def _named(name: str) -> type[FrictionModel] | None:
    """The plugin `name` alone, loading only its entry points (importing every plugin costs
    a second or more); `None` if none loads under that name."""
    if _cache is not None:
        return _cache.get(name) or _runtime.get(name)
    if name not in _named_cache:
        entries = [ep for ep in entry_points(group=ENTRY_POINT_GROUP) if ep.name == name]
        _named_cache[name] = _load(entries).get(name) if entries else None
    return _named_cache[name] or _runtime.get(name)


def refresh_models() -> None:
    """Forget the cached plugin scan; the next lookup rescans the entry points."""
    global _cache
    _cache = None
    _named_cache.clear()


def list_models() -> dict[str, type[FrictionModel]]:
    """All available models, `{name: class}`, sorted by name.

    Entry-point plugins first, then models added with `register_model` (which may not
    shadow a plugin name).
    """
    models = dict(_discover())
    for name, cls in _runtime.items():
        models.setdefault(name, cls)
    return dict(sorted(models.items()))


def register_model(name: str, cls: type[FrictionModel]) -> None:
    """Register a model class under `name` for this process (no packaging needed).

    Packages should prefer the `stickslip.models` entry point; this is for notebooks and
    scripts.
    """
    from ._model import FrictionModel

    if not (isinstance(cls, type) and issubclass(cls, FrictionModel)):
        raise TypeError(f"register_model: {cls!r} is not a subclass of stickslip.FrictionModel")
    if name in _discover() and _discover()[name] is not cls:
        raise PluginError(f"register_model: the name '{name}' is taken by an installed plugin")
    _runtime[name] = cls


def get_model(name: str | type[FrictionModel]) -> type[FrictionModel]:
    """The model class registered as `name` (a class is returned unchanged).

    Raises `PluginError` with the list of known names when there is no such model.
    """
    from ._model import FrictionModel

    if isinstance(name, type):
        if issubclass(name, FrictionModel):
            return name
        raise PluginError(f"{name!r} is not a subclass of stickslip.FrictionModel")
    found = _named(name)
    if found is not None:
        return found
    models = list_models()
    try:
        return models[name]
    except KeyError:
        known = ", ".join(models) or "none installed"
        raise PluginError(f"unknown model '{name}' (known models: {known})") from None


def model_name(cls: type[FrictionModel]) -> str:
    """The registry name of a model class (its class name if it is not registered)."""
    for name, registered in list_models().items():
        if registered is cls:
            return name
    return cls.__name__
