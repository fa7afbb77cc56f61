"""Reading a measured trace's columns from a CSV (with a header) or a MATLAB .mat file."""

from __future__ import annotations

import numpy as np

from .load import StudyError


def read_trace(path: str, wanted) -> dict:
    """The columns `wanted` (those present) of a CSV or .mat trace as float arrays; a file
    that cannot be read is a `StudyError` naming the problem."""
    import os

    if not os.path.isfile(path):
        raise StudyError(path, None, "no such file" if not os.path.lexists(path)
                         else "is not a regular file")  # fmt: skip
    if path.lower().endswith(".mat"):
        from scipy.io import loadmat

        try:
            raw = loadmat(path)
        except Exception:  # scipy raises several kinds for a file that is no .mat
            raise StudyError(path, None, "cannot be read as a MATLAB .mat file") from None
        return {n: np.asarray(raw[n], float).ravel() for n in wanted if n in raw}
    with open(path, encoding="utf-8-sig") as fh:
        header = next(line for line in fh if line.strip() and not line.startswith("#"))
    names = [n.strip() for n in header.split(",")]
    data = np.genfromtxt(path, delimiter=",", comments="#", names=True, dtype=float)
    return {n: np.asarray(data[n], float) for n in wanted if n in names}
