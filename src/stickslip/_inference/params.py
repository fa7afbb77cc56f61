"""The parameters `fit` estimates: the model class, the `fixed` values and the `free` boxes
(an entry of a dict parameter named with a dot, `"threshold_params.sd"`), checked before
anything is simulated; the fit coordinates (log for a parameter whose box is positive);
and the memory one evaluation needs.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from .._errors import ParameterError, ResourceError
from .._memory import memory_limit, past_limit
from .data import refusal

# Peak memory of one evaluation, per simulated cycle and state component: measured 475 B a
# cycle for langevin (3 components) at 2e6 cycles, plain and as a trace (peak RSS).
SIM_BYTES_PER_STATE = 160
MAX_SIM_PATHS = 2**32 - 1  # the simulator numbers its paths with 32 bits


def model_class(model):
    from .._model import ChainModel, FrictionModel
    from .._registry import get_model

    if isinstance(model, str):
        Model = get_model(model)
    elif isinstance(model, type) and issubclass(model, FrictionModel):
        Model = model
    else:
        raise ParameterError("fit", "model", "must be a model name or a FrictionModel class", model)
    if issubclass(Model, ChainModel):
        raise ParameterError(
            "fit", "model", f"{Model.__name__} is a chain of blocks: fit needs a single-block model"
        )
    return Model


def creeping_scales(Model, data, fixed, free, scales):
    """The units a creeping slider (`CreepingSlider`, in SI) meets one force trace's cycles
    in (`Scales.si` of its fixed stiffness); each refusal one line: per-cycle values (its
    cycles carry the state of the ones before, and a run starts in a velocity step's
    transient: only a measured trace's stationary cycles are fitted), a `scales` given, a
    stiffness not fixed. (Several runs: `joint.CreepingRuns`, each run's own units.)"""
    from .._extract import Cycles
    from ..units import Scales

    name = Model.__name__
    if not isinstance(data, Cycles):
        raise ParameterError(
            "fit", "data", f"must be the Cycles of a force trace for {name}: a creeping "
            "slider's cycles carry the state of the ones before and a run starts in a "
            "velocity step's transient, so it is fitted through the trace's measurement, "
            "to its stationary motion, not to per-cycle values",
        )  # fmt: skip
    if scales is not None:
        raise ParameterError("fit", "scales", f"must be left out for {name}: a creeping "
                             "slider is in SI, its units follow from its stiffness")  # fmt: skip
    if "stiffness" in free or not hasattr(fixed, "get") or fixed.get("stiffness") is None:
        raise ParameterError(
            "fit", "fixed", f"must give {name}'s stiffness (N/m, the trace's spring): the "
            "force trace is read as its extension",
        )  # fmt: skip
    return Scales.si(fixed["stiffness"])


def check_fixed(fixed, Model) -> dict[str, Any]:
    if fixed is None:
        return {}
    if not hasattr(fixed, "items"):
        raise ParameterError("fit", "fixed", "must be a dict {name: value}", fixed)
    known = Model.parameters()
    for k in fixed:
        if k not in known:
            raise ParameterError(
                "fit",
                f"fixed['{k}']",
                f"is not a parameter of {Model.__name__} (parameters: {', '.join(known)})",
            )
    return dict(fixed)


def check_free(free, fixed, Model) -> dict[str, tuple[float, float]]:
    """The boxes, checked; a dotted name (`"threshold_params.sd"`) is an entry of a dict
    parameter, whose other entries `fixed` holds (a value `fixed` gives it too is replaced:
    a study's `model.params` names a complete model). With every entry free, `fixed` may
    leave the dict parameter out: it is added to `fixed` (the caller's copy) as `{}`."""
    if not hasattr(free, "items") or not free:
        raise ParameterError("fit", "free", "must be a non-empty dict {name: (low, high)}", free)
    known = Model.parameters()
    out = {}
    for k, box in free.items():
        head, _, entry = str(k).partition(".")
        if head not in known:
            raise ParameterError(
                "fit",
                f"free['{k}']",
                f"is not a parameter of {Model.__name__} (parameters: {', '.join(known)})",
            )
        if entry and head not in fixed:  # every entry free: the dict starts empty
            fixed[head] = {}
        if entry and not hasattr(fixed.get(head), "items"):
            raise ParameterError(
                "fit",
                f"free['{k}']",
                f"names an entry of {head}, which fixed must give as a dict of its other "
                f"entries (or leave out), not {fixed.get(head)!r}",
            )
        try:
            low, high = (float(b) for b in box)
        except (TypeError, ValueError):
            raise ParameterError("fit", f"free['{k}']", "must be a pair (low, high)", box) from None
        if not (math.isfinite(low) and math.isfinite(high) and low < high):
            raise ParameterError("fit", f"free['{k}']", "must be finite with low < high", box)
        if k in fixed:
            raise ParameterError("fit", f"free['{k}']", "is also fixed")
        if not entry and any(str(j).startswith(f"{k}.") for j in free):
            raise ParameterError("fit", f"free['{k}']", "is free with one of its own entries")
        out[str(k)] = (low, high)
    return out


def kwargs_of(fixed: dict, values: dict) -> dict[str, Any]:
    """The model's keyword arguments: `fixed` with the free `values` set, a dotted name
    into its dict parameter (copied, so `fixed` is left as given)."""
    out = dict(fixed)
    for k, v in values.items():
        head, _, entry = k.partition(".")
        if entry:
            out[head] = {**out[head], entry: v}
        else:
            out[k] = v
    return out


def check_box(Model, fixed, free, centre: dict):
    """The model at the box's centre, after building it there and at both ends of each
    axis: a value it refuses is a `ParameterError` naming the free parameter's box."""
    trials = [(None, centre)] + [(k, {**centre, k: b}) for k in free for b in free[k]]
    for name, values in trials:
        try:
            model = Model(**kwargs_of(fixed, values))
        except TypeError as err:  # a required parameter neither fixed nor free
            raise ParameterError(
                "fit",
                "fixed",
                f"with free does not make a {Model.__name__}: {str(err).splitlines()[0]}",
            ) from None
        except (ValueError, ArithmeticError) as err:
            culprit = name or (err.parameter if isinstance(err, ParameterError) else None)
            if isinstance(err, ParameterError):
                reason = f"{err.owner} says {err.parameter} {err.reason}"
            else:
                reason = f"{type(err).__name__}: {str(err).splitlines()[0] if str(err) else ''}"
            if culprit in free:
                raise ParameterError(
                    "fit",
                    f"free['{culprit}']",
                    f"reaches {culprit} = {values[culprit]:.4g}, where {reason}: narrow the box",
                    free[culprit],
                ) from None
            where = f"fixed['{culprit}']" if culprit in fixed else "fixed"
            raise ParameterError(
                "fit",
                where,
                f"with free at the box's centre does not make a {Model.__name__} ({reason})",
            ) from None
        if name is None:
            built = model
    return built


def check_n_sim_memory(n_sim: int, model) -> None:
    """The simulator's memory limit (`stickslip`'s one: half this machine's memory, or
    `STICKSLIP_MEMORY_LIMIT`), so that a fit and a plain simulation refuse alike."""
    per_cycle = SIM_BYTES_PER_STATE * model.state_dim
    words = past_limit(n_sim * per_cycle, f" per evaluated point ({per_cycle} B a simulated cycle)")
    if words is not None:
        raise refusal(
            ResourceError, "n_sim", f"{words}: take at most {memory_limit() // per_cycle:.3g}",
            n_sim,
        )  # fmt: skip
    if n_sim > MAX_SIM_PATHS:
        raise ParameterError(
            "fit", "n_sim", "must be < 2**32 (the simulator numbers its paths with 32 bits)", n_sim
        )


def to_fit_coords(scale, x):
    return np.log(x) if scale == "log" else x


@dataclasses.dataclass(frozen=True)
class ToFit:
    """`(name, x) -> u`: a free parameter's values in fit coordinates (log for a box with
    a positive lower end), as `FitResult.diagnostics.to_fit`; picklable (a fit crosses
    to and from worker processes)."""

    scales: dict[str, str]

    def __call__(self, name: str, x):
        return to_fit_coords(self.scales[name], np.asarray(x))


def from_fit_coords(scale, u):
    return float(np.exp(u)) if scale == "log" else float(u)


def model_kwargs(model) -> dict[str, Any]:
    """The constructor's arguments that rebuild `model`: its `params()` less what they only
    describe (a random threshold's law summary, `threshold_description`)."""
    known = type(model).parameters()
    return {k: v for k, v in model.params().items() if k in known}
