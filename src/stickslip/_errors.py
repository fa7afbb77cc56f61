"""Exceptions with one-line messages that name what is wrong and why."""

from __future__ import annotations

from typing import Any


class StickSlipError(Exception):
    """Base class of the package's own errors."""


class ParameterError(StickSlipError, ValueError):
    """An invalid parameter value.

    The message is one line: `<owner>: parameter '<name>' <reason> (got <value>)`. The
    attributes `owner`, `parameter` and `reason` let callers (the study validator, the CLI)
    re-phrase it in their own terms.
    """

    def __init__(self, owner: str, parameter: str, reason: str, value: Any = None):
        self.owner = owner
        self.parameter = parameter
        self.reason = reason
        self.value = value
        got = "" if value is None else f" (got {value!r})"
        super().__init__(f"{owner}: parameter '{parameter}' {reason}{got}")


class PluginError(StickSlipError, LookupError):
    """A model name that no installed plugin provides, or a plugin that is not a model."""


class DataError(StickSlipError, ValueError):
    """Data that cannot be used as given: a trace without stick-slip structure, per-cycle
    values that are degenerate (constant, too few distinct values, 2-D), non-finite rows.
    The message is one line and states the evidence (counts, levels), never the data."""


class ResourceError(StickSlipError, MemoryError):
    """A request whose memory or size is past what can be done (too many paths, a grid
    too fine for the model's time scales), refused before anything is allocated; the
    message names the figure (bytes, points) and the limit."""


class OutputError(StickSlipError, OSError):
    """An output location that would touch the inputs or a folder of the user's own
    files, or that cannot be written; found before any work is done."""


def check_real(owner: str, name: str, value: Any, *, allow_none: bool = False) -> float | None:
    """Return `value` as a finite float, or raise a `ParameterError` naming `name`."""
    if value is None:
        if allow_none:
            return None
        raise ParameterError(owner, name, "is required and must be a finite number", value)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        try:  # numpy / JAX scalars
            import numpy as np

            arr = np.asarray(value)
            if arr.shape != () or arr.dtype.kind not in "iuf":
                raise TypeError
            value = float(arr)
        except (TypeError, ValueError):
            raise ParameterError(owner, name, "must be a real number", value) from None
    value = float(value)
    if value != value or value in (float("inf"), float("-inf")):
        raise ParameterError(owner, name, "must be finite", value)
    return value


def check_positive(owner: str, name: str, value: Any, *, allow_none: bool = False) -> float | None:
    value = check_real(owner, name, value, allow_none=allow_none)
    if value is not None and value <= 0:
        raise ParameterError(owner, name, "must be > 0", value)
    return value


def check_nonnegative(owner: str, name: str, value: Any) -> float:
    value = check_real(owner, name, value)
    if value < 0:
        raise ParameterError(owner, name, "must be >= 0", value)
    return value


def check_choice(owner: str, name: str, value: Any, choices: tuple[str, ...]) -> str:
    if value not in choices:
        options = ", ".join(repr(c) for c in choices)
        raise ParameterError(owner, name, f"must be one of {options}", value)
    return value


def check_int(owner: str, name: str, value: Any, *, minimum: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        try:
            import numpy as np

            if isinstance(value, np.integer):
                value = int(value)
            else:
                raise TypeError
        except TypeError:
            raise ParameterError(owner, name, "must be an integer", value) from None
    if minimum is not None and value < minimum:
        raise ParameterError(owner, name, f"must be >= {minimum}", value)
    return value


def build_named(owner: str, field: str, table, name: Any, params: Any = None, *,
                params_field: str | None = None, check_value=None, kind: str = "law"):  # fmt: skip
    """An instance of the class `table[name]`, built from the parameters `params` (a
    mapping by name, or None for none), each mistake one line that names `owner` and the
    field: an unknown `name` (the known ones listed), `params` that are not a mapping by
    name, a parameter the class does not take or one it needs without a default (its
    parameters listed), and a `ParameterError` of the class's own checks, renamed to the
    field. A parameter's field is `params_field.key` (just `key` without `params_field`).
    `check_value(owner, field, value)`, if given, checks each value first (`check_real`).
    `kind` is what messages call the classes ("law")."""
    import inspect
    from collections.abc import Mapping

    prefix = f"{params_field}." if params_field else ""
    where = params_field or field
    try:
        cls = table[name]
    except (KeyError, TypeError):
        options = ", ".join(repr(k) for k in table)
        raise ParameterError(owner, field, f"must be one of {options}", name) from None
    params = {} if params is None else params
    if not (isinstance(params, Mapping) and all(isinstance(k, str) for k in params)):
        raise ParameterError(owner, where, f"must be a dict of the {name} {kind}'s parameters "
                             "by name", params)  # fmt: skip
    kinds = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
    taken = [p for p in inspect.signature(cls).parameters.values() if p.kind in kinds]
    takes = f"it takes {', '.join(str(p.replace(annotation=p.empty)) for p in taken)}"
    names = [p.name for p in taken]
    for key in params:
        if key not in names:
            raise ParameterError(owner, prefix + key, f"is not a parameter of the {name} {kind} "
                                 f"({takes})")  # fmt: skip
    for p in taken:
        if p.default is p.empty and p.name not in params:
            raise ParameterError(owner, prefix + p.name, f"is required by the {name} {kind} "
                                 f"({takes})")  # fmt: skip
    values = dict(params)
    if check_value is not None:
        values = {k: check_value(owner, prefix + k, v) for k, v in values.items()}
    try:
        return cls(**values)
    except ParameterError as err:  # the class's own checks, in the caller's terms
        parameter = err.parameter or ""
        named = parameter if not prefix or parameter.startswith(prefix) else prefix + parameter
        raise ParameterError(owner, named, err.reason, err.value) from None
