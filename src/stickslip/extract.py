"""`extract_cycles`, `Cycles`, `read_cycles`: the public face of `stickslip._extract`."""

from __future__ import annotations

from ._extract import COLUMNS as COLUMNS
from ._extract import FORCE_COLUMNS as FORCE_COLUMNS
from ._extract import Cycles as Cycles
from ._extract import extract_cycles as extract_cycles
from ._extract import read_cycles as read_cycles

__all__ = ["COLUMNS", "FORCE_COLUMNS", "Cycles", "extract_cycles", "read_cycles"]
