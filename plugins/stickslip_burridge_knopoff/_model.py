"""A chain of N blocks with springs to their neighbours and to the driver, a friction law
and friction noise per block; every block sticks and slips on its own."""

from __future__ import annotations

import math
from typing import Any

import equinox as eqx

from stickslip import ParameterError
from stickslip.friction import FRICTION_LAWS, FrictionLaw
from stickslip.plugin import (
    ChainModel,
    build_named,
    check_choice,
    check_int,
    check_nonnegative,
    check_positive,
    check_real,
)

_NAME = "burridge-knopoff"


class BurridgeKnopoff(ChainModel):
    r"""Burridge-Knopoff chain: N blocks of unit mass, neighbours coupled by springs $k_c$,
    each pulled by a loading spring $k_p$ from a driver moving at $v_b$, with its own
    friction law and friction noise (white, or Ornstein-Uhlenbeck with correlation time
    $\tau$):
    $$\dot V_i = k_c (u_{i+1} - 2u_i + u_{i-1}) + k_p (v_b t - u_i) - F(V_i) + \eta_i
    \quad (V_i > 0).$$
    A block sticks when its sliding velocity returns to zero and releases when the spring
    force on it exceeds its static limit. Simulate with `stickslip.simulate_chain`.

    **Arguments:** `n_blocks` (N >= 1), `k_c` (>= 0), `k_p` (> 0), `v_b` (> 0), `friction`
    (a `stickslip.friction.FrictionLaw`, or a law's name with `friction_params`), `D` (>= 0),
    `tau` (None: white noise; > 0: OU), `boundary` (`"free"` or `"periodic"`), `threshold`
    (None, or a law of the `random-threshold` plugin by name with `threshold_params`: a
    factor on each block's static limit, drawn afresh at each stick), `event_level`
    (mean sliding velocity below which the chain is quiet: the crossing variable's level for
    the crossing statistics; default 0, the ends of events).

    **Admissible scales** (as for `langevin`): $\sqrt{k_p + 4 k_c}$ and $1/\tau$ at most
    1e12 per time unit, $D = 0$ or a noise level $D / (k_p^{3/2} (F_s/k_p)^2)$ between
    1e-100 and 1e12, and a threshold law within 30 decades of its median.

    With N = 1 and `LinearViscous(static=F_s, viscosity=mu, kinetic=F_k)` it is the
    `langevin` model with $\omega_0^2 = k_p$, $\zeta = \mu$ and
    $x_0 = (F_s - F_k - \mu v_b)/k_p$ (tested).
    """

    n_blocks: int = eqx.field(static=True)
    k_c: float
    k_p: float
    v_b: float
    friction: FrictionLaw
    D: float
    tau: float | None = None
    boundary: str = eqx.field(default="free", static=True)
    threshold: Any = None
    event_level: float = eqx.field(default=0.0, static=True)

    def __init__(
        self, n_blocks, k_c, k_p, v_b, friction, friction_params=None, D=0.0, tau=None,
        boundary="free", threshold=None, threshold_params=None, event_level=0.0,
    ):  # fmt: skip
        self.n_blocks = check_int(_NAME, "n_blocks", n_blocks, minimum=1)
        self.k_c = check_real(_NAME, "k_c", k_c)
        self.k_p = check_real(_NAME, "k_p", k_p)
        self.v_b = check_real(_NAME, "v_b", v_b)
        self.D = check_real(_NAME, "D", D)
        self.tau = check_real(_NAME, "tau", tau, allow_none=True)
        self.boundary = boundary
        self.event_level = check_real(_NAME, "event_level", event_level)
        if isinstance(friction, FrictionLaw):
            if friction_params:
                raise ParameterError(_NAME, "friction_params", "given with a friction law instance")
            self.friction = friction
        else:
            self.friction = build_named(
                _NAME, "friction", FRICTION_LAWS, friction, friction_params,
                params_field="friction_params",
            )  # fmt: skip
        if threshold is None:
            if threshold_params:
                raise ParameterError(_NAME, "threshold_params", "given without a threshold law")
            self.threshold = None
        else:
            from stickslip_random_threshold import make_law

            try:
                self.threshold = make_law(threshold, threshold_params)
            except ParameterError as err:
                raise ParameterError(_NAME, err.parameter, err.reason, err.value) from None

    def __check_init__(self):
        check_nonnegative(_NAME, "k_c", self.k_c)
        check_positive(_NAME, "k_p", self.k_p)
        check_positive(_NAME, "v_b", self.v_b)
        check_nonnegative(_NAME, "D", self.D)
        check_positive(_NAME, "tau", self.tau, allow_none=True)
        check_choice(_NAME, "boundary", self.boundary, ("free", "periodic"))
        check_nonnegative(_NAME, "event_level", self.event_level)
        # The scales of `langevin` (stickslip_langevin._scales): the highest normal mode
        # sqrt(k_p + 4 k_c) and 1/tau as rates; the noise level with omega0 = sqrt(k_p) and
        # the loading spring's stretch at release, F_s / k_p, as the length.
        from stickslip_langevin import check_noise, check_rate

        check_rate(
            _NAME, "k_c", math.sqrt(self.k_p + 4.0 * self.k_c), "sqrt(k_p + 4 k_c)", self.k_c
        )
        if self.tau is not None:
            check_rate(_NAME, "tau", 1.0 / self.tau, "1/tau", self.tau)
        static = float(self.friction.static_limit)
        if not (math.isfinite(static) and static > 0):
            raise ParameterError(_NAME, "friction", "needs a finite static_limit > 0", static)
        check_noise(_NAME, self.D, math.sqrt(self.k_p), static / self.k_p, "k_p^1.5 (F_s/k_p)^2")
        if self.threshold is not None:
            from stickslip_random_threshold import check_spread

            try:
                check_spread(self.threshold)
            except ParameterError as err:
                raise ParameterError(_NAME, err.parameter, err.reason, err.value) from None

    def params(self):
        out = {
            k: getattr(self, k)
            for k in ("n_blocks", "k_c", "k_p", "v_b", "D", "tau", "boundary", "event_level")
        }
        out["friction"] = type(self.friction).__name__
        out["friction_params"] = self.friction.params()
        out["threshold"] = None if self.threshold is None else repr(self.threshold)
        return out

    @classmethod
    def parameters(cls):
        import dataclasses

        M = dataclasses.MISSING
        return {
            "n_blocks": M, "k_c": M, "k_p": M, "v_b": M, "friction": M,
            "friction_params": None, "D": 0.0, "tau": None, "boundary": "free",
            "threshold": None, "threshold_params": None, "event_level": 0.0,
        }  # fmt: skip

    @classmethod
    def example(cls):
        return cls(
            100, k_c=10.0, k_p=1.0, v_b=0.01, friction="velocity-weakening",
            friction_params={"F0": 1.0, "alpha": 2.5, "sigma": 0.01}, D=1e-4, tau=0.1,
        )  # fmt: skip
