"""The per-cycle quantities: one registry that extraction, fits, studies, plots and units read.

A cycle is a slip and the stick that follows it. Each quantity measured on it is one
`Quantity`: its name (the column of a table), its dimension (what a model value is
multiplied by to give SI: a time, a length or a force), its SI unit, the words and symbol
that label an axis, whether it is a positive duration (fitted on a log scale, drawn on a log
axis; a stick too short to see is a zero), and which tables give it:

- `"model"`: every model's simulated cycles (`Ensemble`, `simulate_cycles`);
- `"trace"`: cycles extracted from any measured trace (`extract_cycles`);
- `"force"`: cycles extracted from a force trace (`extract_cycles(..., force=...)`);
- `"slider"`: a `Slider`'s cycles in SI units (`Slider.simulate`);
- `"measurement"`: a model's cycles seen through a `Measurement` (its trace extracted);
- `"fit"`: the columns `fit` reads.

    >>> from stickslip import quantities
    >>> quantities.get("slip_time").unit
    's'
    >>> quantities.names("fit")
    ('slip_time', 'slip_distance', 'stick_time', 'period')

The registry's order is the order of a table's columns.
"""

from __future__ import annotations

import dataclasses

__all__ = ["Quantity", "QUANTITIES", "SI_UNITS", "get", "names"]

# A dimension -> its SI unit.
SI_UNITS = {"time": "s", "length": "m", "force": "N"}


@dataclasses.dataclass(frozen=True)
class Quantity:
    """One per-cycle quantity.

    - `name`: its column in a table;
    - `dimension`: `"time"`, `"length"` or `"force"` (what converts a model value to SI);
    - `label`: words and symbol for an axis (matplotlib mathtext);
    - `symbol`: the symbol alone (mathtext, without dollars), or None;
    - `positive`: a duration (never negative): fitted on a log scale (its zeros apart),
      drawn on a log axis;
    - `given_by`: the tables that have it (see the module's docstring).
    """

    name: str
    dimension: str
    label: str
    symbol: str | None = None
    positive: bool = False
    given_by: frozenset[str] = frozenset()

    def __post_init__(self):
        if self.dimension not in SI_UNITS:
            raise ValueError(f"Quantity {self.name!r}: dimension must be one of {list(SI_UNITS)}")

    @property
    def unit(self) -> str:
        """The SI unit."""
        return SI_UNITS[self.dimension]


def _q(name, dimension, label, symbol=None, positive=False, given_by=()):
    return Quantity(name, dimension, label, symbol, positive, frozenset(given_by))


_CYCLE = ("model", "trace", "force", "slider", "measurement", "fit")
QUANTITIES: dict[str, Quantity] = {
    q.name: q
    for q in (
        _q("release_time", "time", "release time $t_r$", "t_r", False, ("trace", "force")),
        _q("slip_time", "time", "slip time $T_{sl}$", "T_{sl}", True, _CYCLE),
        _q("slip_distance", "length", "slip distance $d = x_0 - x_{sl}$", "d", False, _CYCLE),
        _q("stick_time", "time", "stick time $T_{st}$", "T_{st}", True, _CYCLE),
        _q("period", "time", "period $T = T_{sl} + T_{st}$", "T", True, _CYCLE),
        _q(
            "peak_force",
            "force",
            "peak force $F_s$",
            "F_s",
            False,
            ("force", "slider", "measurement"),
        ),  # fmt: skip
        _q(
            "force_drop",
            "force",
            "force drop $\\Delta F$",
            "\\Delta F",
            False,
            ("force", "slider", "measurement"),
        ),  # fmt: skip
        _q("slider_travel", "length", "slider travel $d + V T_{sl}$", None, False, ("slider",)),
    )
}


def get(name: str) -> Quantity:
    """The quantity called `name` (a KeyError naming the known ones otherwise)."""
    try:
        return QUANTITIES[name]
    except KeyError:
        raise KeyError(f"no per-cycle quantity {name!r}; known: {', '.join(QUANTITIES)}") from None


def names(given_by: str | None = None, *, positive: bool | None = None) -> tuple[str, ...]:
    """The names, in the registry's order, of the quantities that the table `given_by` has
    (all when None), and only the positive durations (`positive=True`) or only the others
    (`positive=False`)."""
    return tuple(
        q.name
        for q in QUANTITIES.values()
        if (given_by is None or given_by in q.given_by)
        and (positive is None or q.positive == positive)
    )
