"""Reading a study: YAML text -> plain data -> `Study`, with one-line errors.

Parsing is kept apart from validation: `read_yaml` turns text into plain data (catching
syntax errors, duplicate keys and a document that is not a mapping), `apply_overrides` sets
`key=value` pairs from the command line, and `Study.model_validate` checks the result. Any
failure is a `StudyError` whose message is one line naming the file, the field and the
reason.
"""

from __future__ import annotations

import os
import pathlib
import re
from typing import Any

import yaml
from pydantic import ValidationError

from .._errors import StickSlipError
from .schema import Study, _yaml_type, first_error, locate, set_path


class StudyError(StickSlipError, ValueError):
    """A study that cannot be read or is invalid. `field` is the dotted location (or None
    for the file as a whole) and `reason` why; the message is one line."""

    def __init__(self, source: str | None, field: str | None, reason: str):
        self.source, self.field, self.reason = source, field, reason
        where = ": ".join(p for p in (source, field) if p)
        super().__init__(f"{where}: {reason}" if where else reason)


class _Loader(yaml.SafeLoader):
    """Safe YAML with two fixes: `1e-4` is a float (YAML 1.1 reads it as a string), and
    a key given twice in one mapping is an error rather than silently the last value."""

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            try:
                hash(key)
            except TypeError:
                raise yaml.constructor.ConstructorError(
                    None, None, "found an unhashable key (a list or mapping)", key_node.start_mark
                ) from None
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"duplicate key '{key}'", key_node.start_mark
                )
            seen.add(key)
        return super().construct_mapping(node, deep=deep)


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(
        r"""^(?:[-+]?(?:[0-9][0-9_]*)\.[0-9_]*(?:[eE][-+]?[0-9]+)?
        |[-+]?(?:[0-9][0-9_]*)(?:[eE][-+]?[0-9]+)
        |\.[0-9_]+(?:[eE][-+][0-9]+)?
        |[-+]?\.(?:inf|Inf|INF)
        |\.(?:nan|NaN|NAN))$""",
        re.X,
    ),
    list("-+0123456789."),
)


def parse_value(text: str) -> Any:
    """A YAML scalar or flow value, as given to `--set key=value`."""
    return yaml.load(text, Loader=_Loader)  # noqa: S506 - _Loader is a SafeLoader


def read_yaml(text: str, source: str | None = None) -> dict:
    """Plain data from YAML text; a `StudyError` for bad syntax or a non-mapping."""
    try:
        data = yaml.load(text, Loader=_Loader)  # noqa: S506 - _Loader is a SafeLoader
    except yaml.MarkedYAMLError as err:
        mark = err.problem_mark or err.context_mark
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        problem = "; ".join(p for p in (err.context, err.problem) if p) or "invalid YAML"
        raise StudyError(source, None, f"YAML syntax error at {where}{problem}") from None
    except yaml.YAMLError as err:
        raise StudyError(source, None, f"YAML error: {str(err).splitlines()[0]}") from None
    if data is None:
        raise StudyError(source, None, "the study is empty")
    if not isinstance(data, dict):
        raise StudyError(
            source, None, f"a study must be a mapping of keys to values (got {_yaml_type(data)})"
        )
    return data


def _override(item) -> tuple[str, str]:
    """`(label, "key=value")`: an override and where it came from (`--set` by default)."""
    if isinstance(item, tuple):
        return item
    return "--set", str(item)


def apply_overrides(data: dict, overrides, source: str | None = None) -> dict:
    """Set `key=value` pairs (dotted keys, YAML values) on study data. An item may be a
    `(label, "key=value")` pair, the label naming its origin in error messages."""
    for item in overrides or ():
        label, text = _override(item)
        key, sep, value = text.partition("=")
        key = key.strip()
        if not sep or not key:
            raise StudyError(label, None, f"expected KEY=VALUE (got {text!r})")
        try:
            parsed = parse_value(value)
        except yaml.YAMLError as err:
            reason = f"value {value!r} is not valid YAML ({str(err).splitlines()[0]})"
            raise StudyError(label, key, reason) from None
        try:
            data = set_path(data, key, parsed)
        except KeyError as err:
            raise StudyError(label, key, str(err.args[0])) from None
    return data


def _blame(loc: str, overrides, source):
    """The origin of a bad field: the override that set it, or the study file."""
    for item in reversed(list(overrides or ())):
        label, text = _override(item)
        key = text.partition("=")[0].strip()
        if loc == key or loc.startswith(key + ".") or key.startswith(loc + "."):
            return label
    return source


def validate(data: dict, source: str | None = None, overrides=None) -> Study:
    """A `Study` from plain data; a one-line `StudyError` naming the first bad field (and
    the `--set` that set it, if one did)."""
    try:
        return Study.model_validate(data)
    except ValidationError as err:
        loc, reason = locate(first_error(err))
        origin = _blame(loc, overrides, source)
        if origin == "--param":  # the user named the setting, not the sweep block
            loc = loc.removeprefix("sweep.parameters.")
        raise StudyError(origin, loc, reason) from None


def load_study(source: str | os.PathLike | dict | Study, overrides=None) -> Study:
    """A validated `Study` from a YAML file, a dict, or a `Study` (copied with `overrides`,
    a list of `"key=value"` strings, applied first)."""
    if isinstance(source, Study):
        if not overrides:
            return source
        data = source.model_dump(exclude_unset=True)
        return validate(apply_overrides(data, overrides), None, overrides)
    if isinstance(source, dict):
        return validate(apply_overrides(source, overrides), None, overrides)
    path = pathlib.Path(source)
    name = str(source)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise StudyError(name, None, "no such file") from None
    except IsADirectoryError:
        raise StudyError(name, None, "is a directory, not a study file") from None
    except UnicodeDecodeError:
        raise StudyError(name, None, "is not a UTF-8 text file") from None
    except OSError as err:
        raise StudyError(name, None, f"cannot be read ({err.strerror})") from None
    data = read_yaml(text, name)
    return validate(apply_overrides(data, overrides, name), name, overrides)


def _sweep_override(block: dict) -> tuple[str, str]:
    """An override that replaces the sweep block (for `stickslip sweep --param`)."""
    import json

    return "--param", "sweep=" + json.dumps(block)
