"""The Langevin slip phase with a static threshold drawn afresh at every release."""

from __future__ import annotations

import equinox as eqx
import numpy as np
from stickslip_langevin import Langevin, LangevinSlip

from stickslip.plugin import check_real, jax

from ._laws import ThresholdLaw, check_spread, make_law

_NAME = "random-threshold"


class RandomThreshold(LangevinSlip):
    r"""Langevin model with a static threshold drawn afresh at every release.

    The `langevin` slip phase (eqs. 8-9), with the threshold $x_0$ drawn for each cycle from a
    law chosen by name: asperity size and contact aging make the static friction vary from
    one stick to the next.

    The slip starts at $(x_0, v_b)$ with $x_0$ drawn for that cycle; the stick lasts until the
    position reaches the *next* cycle's threshold, $T_{st} = \max(0, (x_0' - x_{sl})/v_b)$.
    The exact estimator integrates over $x_0$ by quadrature (a mixture of exact Gaussian
    results).

    **Arguments:** `omega0`, `zeta`, `D`, `v_b`, `tau`, `eta0` as for `langevin`;
    `threshold`, the law's name: `"normal"` (`mean`, `sd`; truncated to $x_0 > 0$),
    `"lognormal"` (`median`, `sigma`), `"uniform"` (`low`, `high` with $0 < $ low), or
    `"weibull"` (`shape`, `scale`); `threshold_params`, a dict of the law's parameters.

    **Admissible scales**: those of `langevin` with the median threshold as $x_0$, and a law
    whose 1e-12 and 1 - 1e-12 quantiles lie within 30 decades of its median (e.g. lognormal
    sigma <= 9.8, Weibull shape >= 0.4): a wider law draws thresholds of 0 or inf.
    """

    omega0: float
    zeta: float
    D: float
    v_b: float
    threshold: ThresholdLaw
    tau: float | None = None
    eta0: str = eqx.field(default="zero", static=True)

    def __init__(
        self, omega0, zeta, D, v_b, threshold, threshold_params=None, tau=None, eta0="zero"
    ):
        self.omega0 = check_real(_NAME, "omega0", omega0)
        self.zeta = check_real(_NAME, "zeta", zeta)
        self.D = check_real(_NAME, "D", D)
        self.v_b = check_real(_NAME, "v_b", v_b)
        self.tau = check_real(_NAME, "tau", tau, allow_none=True)
        self.eta0 = eta0
        self.threshold = make_law(threshold, threshold_params)

    def __check_init__(self):
        self._check_slip(_NAME)
        check_spread(self.threshold)
        self._check_scales(_NAME)

    def _length_scale(self):
        return self.threshold.spread()[1]  # the median threshold

    def params(self):
        from ._laws import THRESHOLD_LAWS, describe

        out = {k: getattr(self, k) for k in ("omega0", "zeta", "D", "v_b", "tau", "eta0")}
        name = next(k for k, v in THRESHOLD_LAWS.items() if isinstance(self.threshold, v))
        import dataclasses

        out["threshold"] = name
        out["threshold_params"] = {
            f.name: getattr(self.threshold, f.name) for f in dataclasses.fields(self.threshold)
        }
        out["threshold_description"] = describe(self.threshold)
        return out

    @classmethod
    def parameters(cls):
        import dataclasses

        return {
            "omega0": dataclasses.MISSING, "zeta": dataclasses.MISSING, "D": dataclasses.MISSING,
            "v_b": dataclasses.MISSING, "threshold": dataclasses.MISSING,
            "threshold_params": dataclasses.MISSING, "tau": None, "eta0": "zero",
        }  # fmt: skip

    @classmethod
    def embed(cls, model):
        """The arguments that make this class reproduce `model`, a special case of it, or
        None: a `langevin` model is a normal threshold of mean `x0` and sd 0 (the same
        slip, the same sticks). `compare_fits` reads it to know which candidates nest."""
        if not isinstance(model, Langevin):
            return None
        p = model.params()
        out = {k: p[k] for k in ("omega0", "zeta", "D", "v_b", "tau", "eta0")}
        return {**out, "threshold": "normal", "threshold_params": {"mean": p["x0"], "sd": 0.0}}

    @classmethod
    def example(cls):
        return cls(1.0, 0.1, 0.4, 1.0, "lognormal", {"median": 1.0, "sigma": 0.25}, tau=0.1)

    # The slip phase is the Langevin one (LangevinSlip); only the threshold is random.
    def slip_phase(self):
        # The `langevin` model with the same slip (its threshold, the median, and `eta0` are
        # used only at release): every threshold law runs on the plain model's compiled loops.
        return Langevin(
            self.omega0, self.zeta, self.D, self.v_b, self._length_scale(), tau=self.tau
        )

    def threshold_at(self, key):
        return self.threshold.sample(jax.random.fold_in(key, 1))

    def mean_threshold(self):
        return self.threshold.average()

    def onset_mixture(self, nodes=32):
        lg = self.linear_gaussian()
        m0, P0 = np.asarray(lg.m0, float), np.asarray(lg.P0, float)
        values, weights = self.threshold.quadrature(nodes)
        m0s = np.repeat(m0[None], values.size, axis=0)
        m0s[:, 0] = values
        return m0s, np.repeat(P0[None], values.size, axis=0), weights


class HeldRandomThreshold(RandomThreshold):
    r"""`random-threshold` whose force cannot jump at a release.

    The same slip, the same threshold laws and arguments. A stick that ends where the force
    is already past the threshold drawn for the next release (a slip the friction noise
    stopped early, followed by a low threshold) releases at once *from where it is*:
    the next slip starts at $x_0 = \max(x_0', x_{sl})$ with $T_{st} = 0$. The paper's
    sharp reset (`random-threshold`, eq. 9) starts that slip from $x_0'$ itself, below
    the force the spring holds: the force drops by $x_{sl} - x_0'$ with no slip to drop it.

    Successive cycles then depend on each other (`carries_state`): `simulate_cycles`, and a
    fit through a force trace's measurement, run the chain. Every path's first slip, the
    first-passage ensembles of `simulate` and the exact estimator's densities start from
    the threshold law as `random-threshold`'s do. Where the thresholds' law keeps the
    stick well below the next threshold (a small friction noise, a narrow law) the two
    models give the same cycles; on a slider with 5 % of its releases past the threshold
    the reset biased a fit's threshold mean up and its noise intensity down.
    """

    carries_state = True

    def release(self, key, y_stick):
        y_next = self.onset_state(key)
        x = self.state_names.index("x")
        y_next = y_next.at[x].set(jax.numpy.maximum(y_next[x], y_stick[x]))
        return self.stick_duration(y_stick, y_next), y_next
