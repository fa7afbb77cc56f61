"""`Cycles`: the table `extract_cycles` returns, and its CSV form with the settings kept."""

from __future__ import annotations

import dataclasses
import json
import math
import os
from typing import Any

import numpy as np

from .._errors import DataError
from ..quantities import names

COLUMNS = names("trace")  # every trace's cycles
FORCE_COLUMNS = names("force")  # a force trace's
_MAGIC = "# stickslip cycles"


@dataclasses.dataclass(frozen=True, eq=False)
class Cycles:
    """The cycles found by `extract_cycles`.

    - `table`: a dict of equal-length arrays, one row per complete cycle (a slip whose
      release and stick were both seen, and the stick that follows it up to the next
      release): `release_time`, `slip_time` $T_{sl}$, `slip_distance` $d = x_0 - x_{sl}$,
      `stick_time` $T_{st}$, `period` $T = T_{sl} + T_{st}$; with force input also
      `peak_force` (the force at the release) and `force_drop` (release less stick).
    - `info`: how they were found: every setting and threshold (`v_b` given and estimated,
      `tol`, `sampling_interval` (the median), the noise level, the units, ...). It is
      written into the CSV's `#` header and restored by `Cycles.from_csv`.
    """

    table: dict[str, np.ndarray]
    info: dict[str, Any]

    def __len__(self) -> int:
        # (any column: a table cut to the columns a fit takes may lack the period)
        return int(next(iter(self.table.values()), np.empty(0)).size)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.table[name]

    def to_csv(self, path: str | os.PathLike | None = None) -> str:
        """The table as CSV text: a `#` header block with `info` (one `# key: JSON` line
        each), the column names, one row per cycle. Written to `path` if given."""
        names = list(self.table)
        lines = [_MAGIC]
        lines += [f"# {key}: {json.dumps(_plain(value))}" for key, value in self.info.items()]
        lines.append(",".join(names))
        if len(self):
            rows = np.column_stack([self.table[k] for k in names])
            lines += [",".join(f"{value:.12g}" for value in row) for row in rows]
        text = "\n".join(lines) + "\n"
        if path is not None:
            with open(path, "w", encoding="utf-8") as f:
                f.write(text)
        return text

    @classmethod
    def from_csv(cls, path: str | os.PathLike) -> Cycles:
        """Read a table written by `to_csv`, with its `info`; a `DataError` for anything
        else (the message names the line, never its content)."""
        return read_cycles(path)

    def __repr__(self) -> str:
        tol = self.info.get("tol", self.info.get("noise_sd", float("nan")))
        return f"Cycles(n={len(self)}, tol={tol:.3g}, v_b={self.info.get('v_b')})"


def read_cycles(path: str | os.PathLike) -> Cycles:
    """A `Cycles` from a CSV written by `Cycles.to_csv` (settings restored from its header)."""
    where = os.fspath(path)
    try:
        with open(path, encoding="utf-8-sig") as f:
            lines = f.read().splitlines()
    except UnicodeDecodeError as err:
        raise DataError(f"{where}: not a UTF-8 text file (byte {err.start})") from None
    except OSError as err:
        raise DataError(f"{where}: cannot read the file ({err.strerror})") from None
    info: dict[str, Any] = {}
    k = 0
    while k < len(lines) and lines[k].startswith("#"):
        body = lines[k][1:].strip()
        if k > 0 and body:
            key, sep, value = body.partition(":")
            try:
                if not sep:
                    raise ValueError
                info[key.strip()] = json.loads(value)
            except ValueError:
                raise DataError(f"{where}: line {k + 1}: not a '# key: value' setting") from None
        k += 1
    if k == len(lines):
        raise DataError(f"{where}: no column header after the settings")
    names = [n.strip() for n in lines[k].split(",")]
    missing = [c for c in COLUMNS if c not in names]
    if missing or len(set(names)) != len(names):
        raise DataError(
            f"{where}: line {k + 1}: the columns must be distinct and include "
            f"{', '.join(COLUMNS)}" + (f" ({', '.join(missing)} missing)" if missing else "")
        )
    rows = []
    for j, line in enumerate(lines[k + 1 :], start=k + 2):
        if not line.strip():
            continue
        try:
            row = [float(c) for c in line.split(",")]
        except ValueError:
            raise DataError(f"{where}: line {j}: a value is not a number") from None
        if len(row) != len(names):
            raise DataError(f"{where}: line {j}: {len(row)} values for {len(names)} columns")
        rows.append(row)
    data = np.array(rows, dtype=float).reshape(len(rows), len(names))
    return Cycles({n: data[:, i] for i, n in enumerate(names)}, info)


def _plain(value):
    """JSON-ready: NumPy scalars to Python, non-finite floats to strings JSON can hold."""
    if isinstance(value, (np.generic,)):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    return value
