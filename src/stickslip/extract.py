"""`extract_cycles`, `Cycles`, `read_cycles`, `analyse_run`, `Run`: the public face of
`stickslip._extract`."""

from __future__ import annotations

from ._extract import COLUMNS as COLUMNS
from ._extract import FORCE_COLUMNS as FORCE_COLUMNS
from ._extract import Cycles as Cycles
from ._extract import Run as Run
from ._extract import analyse_run as analyse_run
from ._extract import extract_cycles as extract_cycles
from ._extract import read_cycles as read_cycles

__all__ = [
    "COLUMNS",
    "FORCE_COLUMNS",
    "Cycles",
    "Run",
    "analyse_run",
    "extract_cycles",
    "read_cycles",
]
