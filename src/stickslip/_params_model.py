"""The parameter model of a model plugin: the pydantic model that checks `model.params`.

A plugin owns it. By default it is made from the model's `parameters()` (names and
defaults) and the annotations of its fields (`float`, `float | None`, `int`, `str`):
unknown names, missing required ones and wrong types are caught by pydantic; the values
are then checked by constructing the model, whose own validation names the parameter. A
plugin may return its own pydantic model from `FrictionModel.params_model()` instead.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any

from pydantic import BaseModel, ConfigDict, create_model

_KNOWN: dict[str, Any] = {
    "float": float,
    "float | None": float | None,
    "None | float": float | None,
    "int": int,
    "str": str,
    "bool": bool,
}


class ParamsBase(BaseModel):
    """Base of every parameter model: unknown keys are errors, types are strict (an int is
    accepted where a float is expected, nothing else is converted)."""

    model_config = ConfigDict(extra="forbid", strict=True, validate_default=False)


@functools.cache
def default_params_model(cls) -> type[BaseModel]:
    """A strict pydantic model of `cls.parameters()`, typed from the field annotations."""
    fields = {f.name: f for f in dataclasses.fields(cls)} if dataclasses.is_dataclass(cls) else {}
    spec: dict[str, Any] = {}
    for name, default in cls.parameters().items():
        ann = fields[name].type if name in fields else None
        if not isinstance(ann, str):
            ann = getattr(ann, "__name__", None)
        typ = _KNOWN.get(ann, Any)
        required = default is dataclasses.MISSING
        if typ is not Any and not required and default is None:
            typ = typ | None
        spec[name] = (typ, ... if required else default)
    model = create_model(
        f"{cls.__name__}Params",
        __base__=ParamsBase,
        __doc__=(cls.__doc__ or "").strip().splitlines()[0] if cls.__doc__ else None,
        **spec,
    )
    return model
