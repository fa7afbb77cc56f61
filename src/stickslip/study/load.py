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
from .schema import Study, first_error, locate, set_path, short, yaml_type


class StudyError(StickSlipError, ValueError):
    """A study that cannot be read or is invalid. `field` is the dotted location (or None
    for the file as a whole) and `reason` why; the message is one line."""

    def __init__(self, source: str | None, field: str | None, reason: str):
        self.source, self.field, self.reason = source, field, reason
        where = ": ".join(p for p in (source, field) if p)
        super().__init__(_one_line(f"{where}: {reason}" if where else reason))


_MAX_MESSAGE = 400  # characters of a message; a value in it is cut shorter where it is made


def _one_line(text: str) -> str:
    """One printable line of at most `_MAX_MESSAGE` characters (longer ends in '...')."""
    text = " ".join(text.split())
    text = "".join(c if c.isprintable() else ascii(c)[1:-1] for c in text)
    return text if len(text) <= _MAX_MESSAGE else text[: _MAX_MESSAGE - 3] + "..."


# Bounds of a study file, far past any real study (a few kB, a few levels deep, a sweep of
# at most `schema.MAX_SWEEP_POINTS` points): a file past them is a mistake or an attack
# (a "billion laughs" of nested aliases, thousands of nested lists) and is refused before
# it is built, instead of exhausting the memory or Python's recursion limit.
MAX_BYTES = 10 * 2**20
MAX_DEPTH = 50
MAX_NODES = 200_000


class _TooDeep(yaml.composer.ComposerError):
    pass


class _Loader(yaml.SafeLoader):
    """Safe YAML with fixes: `1e-4` is a float (YAML 1.1 reads it as a string); a key given
    twice in one mapping is an error rather than silently the last value; nesting deeper
    than `MAX_DEPTH` levels, or a document that expands (every alias counted at each use)
    to more than `MAX_NODES` values, is an error before anything is built."""

    def __init__(self, stream):
        super().__init__(stream)
        self._depth = 0

    def compose_node(self, parent, index):
        self._depth += 1
        try:
            if self._depth > MAX_DEPTH:
                mark = self.peek_event().start_mark
                raise _TooDeep(None, None, f"nested deeper than {MAX_DEPTH} levels", mark)
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def get_single_node(self):
        node = super().get_single_node()
        if node is not None:
            _check_expansion(node)
        return node

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


class _TooLarge(yaml.YAMLError):
    def __init__(self, path: str, reason: str):
        super().__init__(reason)
        self.path, self.reason = path, reason


def _check_expansion(root: yaml.Node):
    """Refuse a document whose expanded tree (aliases repeated at each use) has more than
    `MAX_NODES` nodes, is deeper than `MAX_DEPTH` levels, or refers to itself. Sizes are
    counted per distinct node without expanding anything, so a bomb costs no more than its
    own text; the error names the deepest mapping key that holds the excess."""
    size: dict[int, int] = {}
    depth: dict[int, int] = {}
    active: set[int] = set()

    def children(node):
        if isinstance(node, yaml.MappingNode):
            return [n for pair in node.value for n in pair]
        if isinstance(node, yaml.SequenceNode):
            return list(node.value)
        return []

    stack = [(root, False)]  # iterative post-order: aliases can chain past the recursion limit
    while stack:
        node, done = stack.pop()
        key = id(node)
        if done:
            active.discard(key)
            kids = children(node)
            size[key] = min(1 + sum(size[id(k)] for k in kids), MAX_NODES + 1)
            depth[key] = 1 + max((depth[id(k)] for k in kids), default=0)
            continue
        if key in size:
            continue
        if key in active:
            raise _TooLarge("", "an alias refers to its own anchor (a recursive structure)")
        active.add(key)
        stack.append((node, True))
        stack.extend((k, False) for k in children(node) if id(k) not in size)
    if size[id(root)] > MAX_NODES:
        reason = f"expands to more than {MAX_NODES} values (each alias counted at each use)"
        raise _TooLarge(_where(root, size, MAX_NODES, 0), reason)
    if depth[id(root)] > MAX_DEPTH:
        reason = f"is nested deeper than {MAX_DEPTH} levels (aliases expanded)"
        raise _TooLarge(_where(root, depth, MAX_DEPTH, 1), reason)


def _where(root, metric: dict[int, int], limit: int, per_level: int) -> str:
    """The dotted key path, for the error message: from the top, into the mapping entry
    whose value is past `limit` on `metric` (size, or depth: `per_level` 1, the levels
    above counted), as deep as one is."""
    path: list[str] = []
    node = root
    while isinstance(node, yaml.MappingNode) and len(path) < MAX_DEPTH:
        entry = max(node.value, key=lambda kv: metric.get(id(kv[1]), 0), default=None)
        if entry is None or metric.get(id(entry[1]), 0) <= limit - per_level * (len(path) + 1):
            break
        key, node = entry
        if not isinstance(key, yaml.ScalarNode):
            break
        path.append(key.value[:60])
    return ".".join(path)


def parse_value(text: str) -> Any:
    """A YAML scalar or flow value, as given to `--set key=value`."""
    return yaml.load(text, Loader=_Loader)  # noqa: S506 - _Loader is a SafeLoader


def read_yaml(text: str, source: str | None = None) -> dict:
    """Plain data from YAML text; a `StudyError` for bad syntax or a non-mapping."""
    try:
        data = yaml.load(text, Loader=_Loader)  # noqa: S506 - _Loader is a SafeLoader
    except _TooLarge as err:
        raise StudyError(source, err.path or None, err.reason) from None
    except _TooDeep as err:
        mark = err.problem_mark
        reason = f"YAML {err.problem} (line {mark.line + 1}, column {mark.column + 1})"
        raise StudyError(source, None, reason) from None
    except yaml.MarkedYAMLError as err:
        mark = err.problem_mark or err.context_mark
        where = f"line {mark.line + 1}, column {mark.column + 1}: " if mark else ""
        if "2002:merge" in str(err.problem):  # valid YAML, a feature studies do without
            reason = (f"a YAML merge key '<<' at {where.rstrip(': ')} is not supported: write "
                      "the keys out (an alias of a whole value, *name, works)")  # fmt: skip
            raise StudyError(source, None, reason) from None
        problem = "; ".join(p for p in (err.context, err.problem) if p) or "invalid YAML"
        raise StudyError(source, None, f"YAML syntax error at {where}{problem}") from None
    except yaml.YAMLError as err:
        raise StudyError(source, None, f"YAML error: {str(err).splitlines()[0]}") from None
    if data is None:
        raise StudyError(source, None, "the study is empty")
    if not isinstance(data, dict):
        raise StudyError(
            source, None, f"a study must be a mapping of keys to values (got {yaml_type(data)})"
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
            raise StudyError(label, None, f"expected KEY=VALUE (got {short(text)})")
        try:
            parsed = parse_value(value)
        except yaml.YAMLError as err:
            reason = f"value {short(value)} is not valid YAML ({str(err).splitlines()[0]})"
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
        with open(path, "rb") as f:  # at most MAX_BYTES: the name may be an endless device
            raw = f.read(MAX_BYTES + 1)
    except FileNotFoundError:
        raise StudyError(name, None, "no such file") from None
    except IsADirectoryError:
        raise StudyError(name, None, "is a directory, not a study file") from None
    except OSError as err:
        raise StudyError(name, None, f"cannot be read ({err.strerror})") from None
    if len(raw) > MAX_BYTES:
        raise StudyError(name, None, f"is larger than {MAX_BYTES // 2**20} MiB: not a study file")
    try:
        text = raw.decode("utf-8-sig")  # a byte-order mark, as some editors write, is fine
    except UnicodeDecodeError as err:
        reason = f"is not a UTF-8 text file (byte {err.start + 1} is not UTF-8)"
        raise StudyError(name, None, reason) from None
    data = read_yaml(text, name)
    return validate(apply_overrides(data, overrides, name), name, overrides)


def sweep_override(block: dict) -> tuple[str, str]:
    """An override that replaces the sweep block (for `stickslip sweep --param`)."""
    import json

    return "--param", "sweep=" + json.dumps(block)
