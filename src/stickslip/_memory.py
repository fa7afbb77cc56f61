"""How much memory a run may use, and the one refusal past it (in GiB, for every caller:
the simulator, the estimator's grids, a fit, its goodness of fit, a trace read from disk)."""

from __future__ import annotations

import math
import os

from ._errors import ParameterError, ResourceError

MEMORY_FRACTION = 0.5  # of this machine's physical memory: the default memory limit of a run
MEMORY_FALLBACK = 8e9  # where the physical memory cannot be read (bytes)
GIB = 2**30


def memory_limit() -> float:
    """Bytes a run may use: `STICKSLIP_MEMORY_LIMIT` (bytes) if set, else `MEMORY_FRACTION`
    of the machine's physical memory."""
    env = os.environ.get("STICKSLIP_MEMORY_LIMIT")
    if env:
        try:
            value = float(env)
        except ValueError:
            value = math.nan
        if not (math.isfinite(value) and value > 0):
            raise ParameterError(
                "environment", "STICKSLIP_MEMORY_LIMIT", "must be a number of bytes > 0", env
            )
        return value
    try:
        return MEMORY_FRACTION * os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):  # not a POSIX system
        return MEMORY_FALLBACK


def past_limit(nbytes: float, detail: str = "") -> str | None:
    """None when `nbytes` fits under `memory_limit()`; else the words of the refusal:
    "needs about X GiB{detail}, past the limit of Y GiB (where the limit comes from)"."""
    limit = memory_limit()
    if nbytes <= limit:
        return None
    source = (
        "STICKSLIP_MEMORY_LIMIT"
        if os.environ.get("STICKSLIP_MEMORY_LIMIT")
        else f"{MEMORY_FRACTION:g} of this machine's memory; STICKSLIP_MEMORY_LIMIT sets it"
    )
    return (
        f"needs about {nbytes / GIB:.3g} GiB{detail}, past the limit of {limit / GIB:.3g} GiB "
        f"({source})"
    )


def check_memory(owner: str, what: str, nbytes: float, advice: str) -> None:
    """Refuse, before anything is allocated, a request estimated at `nbytes` past
    `memory_limit()`: "{owner}: {what} needs about X GiB, past the limit of Y GiB (...):
    {advice}"."""
    words = past_limit(nbytes)
    if words is not None:
        raise ResourceError(f"{owner}: {what} {words}: {advice}")
