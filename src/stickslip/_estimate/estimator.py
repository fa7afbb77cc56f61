"""`CrossingEstimator`: first-passage statistics from level-crossing series."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .._errors import ParameterError, check_choice, check_int, check_positive
from .._jax import jax
from .._model import CreepingSlider, FrictionModel, time_scales, to_arrays
from .._notes import collecting_notes, note
from . import gaussian as G
from . import series
from .sources import EmpiricalSource, GaussianSource

METHODS = ("truncation", "decoupling")


class ApproximationWarning(UserWarning):
    """A level-crossing approximation left its range of validity (a negative density or
    escape rate, a truncation that never normalises): values are returned unclipped."""


# Default grid step: DEFAULT_DT, or a fifth of the model's fastest time scale if shorter.
DEFAULT_DT = 0.01
DT_PER_SCALE = 5.0
MASS_TOL = 1e-2  # a density's mass off by more than this from what it must carry warns
# Groups of paths of the empirical estimator's jackknife: its standard error has B - 1 = 19
# degrees of freedom (about 16 % relative error), for B evaluations of the estimate.
ERROR_GROUPS = 20


def cell_average(f, edges, spacing: float):
    """Average of `f` over each cell between consecutive `edges` (midpoint rule, points at
    most `spacing` apart, at most 1000 per cell)."""
    k = int(min(1000, max(4, math.ceil(float(np.max(np.diff(edges))) / spacing))))
    u = (np.arange(k) + 0.5) / k
    x = edges[:-1, None] + np.diff(edges)[:, None] * u[None, :]
    return np.asarray(f(x.ravel()), float).reshape(x.shape).mean(axis=1)


class CrossingEstimator:
    r"""Level-crossing (Rice-Stratonovich) statistics of a stick-slip model.

    The slip ends at the first upcrossing of the crossing variable $v$ through the stick level
    $v_b$. Its density $\mathcal F(t)$ is the series (6) of the upcrossing densities $n_k$;
    `first_passage` gives the truncations $\mathcal F_n^{(k)}$ and the cumulant (decoupling)
    approximations $\mathcal F_g^{(k)}$, $k = 1, 2$; the densities of slip times (eq. 3),
    slip distances (eq. 4) and periods (eq. 2) follow from the joint $\mathcal F(x, t)$.

    **From a linear-Gaussian model** (`ensemble=None`) the $n_k$ are closed-form Gaussian
    integrals (`n2` with the bivariate normal distribution function):

    - `exact` is True when no noise enters $\dot v$ directly (Ornstein-Uhlenbeck friction
      noise, or $D = 0$): $a = \dot v$ has finite variance and Rice's formula is exact;
    - with white noise in $\dot v$ (the paper's eq. 8) $v$ has no derivative, its upcrossing
      rate is infinite, and the paper's $n_1$ rests on a closure, $a \mid x, v$ normal with
      variance $\sigma_a^2$ (`closure_variance`, default $2D$, the noise intensity of $\dot
      v$); `exact` is then False. The closure uses $E[a^+]$: the paper's eq. (12) as printed
      equals $E[a^-]$, a sign slip (see the docs).

    A random onset (e.g. `eta0="stationary"`) is handled by Gauss-Legendre quadrature over the
    initial rate $a(0)$: the slip ends at once with probability $p_0 = P(a(0) \ge 0)$
    (`immediate_probability`) and every other onset is a Gaussian component; each
    approximation is applied per component and the results are mixed. The densities are the
    continuous part: they carry mass $1 - p_0$ at most.

    **From simulation** (`ensemble=` an `Ensemble` made with `record_upcrossings=K`, any
    model): $n_1$ and $\int_0^t n_2(t, s)\,ds$ are histograms of the recorded upcrossings
    of the free slip process, fed to the same series. `exact` is False. The estimates are
    complete up to `t_complete` (no path had more than K upcrossings before it). Each
    estimate has a `*_se` companion (`n1_se`, `first_passage_se`, ...): its sampling error,
    by a delete-a-group jackknife over the paths (zero for the exact formulas).

    **Arguments:**

    - `model`: a `FrictionModel` (with a linear-Gaussian description unless `ensemble` is
      given).
    - `ensemble`: simulated upcrossings for the empirical estimator.
    - `closure_variance`: $\sigma_a^2$ of the white-noise closure.
    - `dt`: step of the time grid on which the series are summed (default 0.01, or a fifth
      of the model's fastest time scale $1/\max|\mathrm{eig}(A)|$ where that is shorter;
      0.05 for the empirical estimator, whose histograms need counts).
    - `horizon`: end of the time grid for the position-resolved densities (slip distance,
      period); default: where the first-order survival $e^{-\int n_1}$ falls below 1e-4.
    - `quadrature_nodes`: Gauss-Legendre nodes over a random onset.
    - `x_points`: positions per grid time (uniform in the standardised position) for the
      position-resolved densities.
    - `joint_dt`: time step of the second-order position-resolved correction (default
      `horizon / 300`; its cost grows as `x_points * (horizon / joint_dt)**2`).
    - `mixing`: with a random onset (a random threshold, a random initial noise),
      `"components"` (the default for exact sources) applies each approximation to every
      onset component and mixes the results; `"process"` applies it once to the mixed
      crossing process, which is what simulated crossings give (the only, and default,
      choice for the empirical estimator). The series are nonlinear, so the two differ;
      where measured, `"components"` is slightly the closer to simulation (slip-time L1
      0.337 against 0.348 for a lognormal threshold with sigma = 0.6; 0.371 against 0.387
      for a uniform one on [0.2, 2.5]; order 1, docs/models.md).
    - `progress`: a progress bar for the second-order integrals that take more than
      about 2 s (default: on a terminal).
    - `error_groups`: groups of paths $B$ of the empirical estimator's jackknife (the
      `*_se` methods; at most one group per path).
    """

    def __init__(
        self,
        model: FrictionModel,
        ensemble=None,
        *,
        closure_variance: float | None = None,
        dt: float | None = None,
        horizon: float | None = None,
        quadrature_nodes: int = 32,
        x_points: int = 96,
        joint_dt: float | None = None,
        mixing: str | None = None,
        progress: bool | None = None,
        error_groups: int = ERROR_GROUPS,
    ):
        owner = "CrossingEstimator"
        if not isinstance(model, FrictionModel):
            raise TypeError(f"{owner}: model must be a FrictionModel instance, got {model!r}")
        if isinstance(model, CreepingSlider):
            raise ParameterError(
                owner, "model",
                f"{type(model).__name__} creeps instead of sticking: it has no first-passage "
                "level for crossing statistics (simulate_cycles gives its cycles)",
            )  # fmt: skip
        self.model = model
        self.horizon = check_positive(owner, "horizon", horizon, allow_none=True)
        self.joint_dt = check_positive(owner, "joint_dt", joint_dt, allow_none=True)
        quadrature_nodes = check_int(owner, "quadrature_nodes", quadrature_nodes, minimum=1)
        x_points = check_int(owner, "x_points", x_points, minimum=4)
        error_groups = check_int(owner, "error_groups", error_groups, minimum=2)
        self.quadrature_nodes = quadrature_nodes
        self._settings = dict(
            closure_variance=closure_variance, dt=dt, horizon=horizon, x_points=x_points,
            joint_dt=joint_dt, mixing=mixing, progress=progress,
        )  # fmt: skip
        self._twin = None
        self.level = float(np.asarray(model.stick_level))
        if mixing is None:
            mixing = "components" if ensemble is None else "process"
        self.mixing = check_choice(owner, "mixing", mixing, ("components", "process"))
        if ensemble is not None:
            up = getattr(ensemble, "upcrossings", ensemble)
            if up is None or not hasattr(up, "times"):
                raise ParameterError(
                    owner, "ensemble", "must carry upcrossings: simulate(..., record_upcrossings=K)"
                )
            if closure_variance is not None:
                raise ParameterError(
                    owner, "closure_variance", "does not apply to simulated crossings"
                )
            self.dt = check_positive(owner, "dt", 0.05 if dt is None else dt)
            onsets = up.onset_position[~up.immediate]
            if self.mixing == "components" and onsets.size and np.ptp(onsets) > 0:
                raise ParameterError(
                    owner,
                    "mixing",
                    "simulated crossings mix every onset into one process: use 'process'",
                )
            self.exact = False
            self.closure_variance = None
            self._upcrossings = up
            self.error_groups = min(error_groups, up.n_paths)
            self._source = EmpiricalSource(up)
            self.t_complete = self._source.t_complete
        else:
            dt = check_positive(owner, "dt", dt, allow_none=True)
            self._source = self._gaussian(model, closure_variance, quadrature_nodes, x_points)
            if dt is None:
                # The grid follows the model: at most a fifth of its fastest time scale (the
                # onset transient of n1 lasts about the noise's correlation time).
                # DEFAULT_DT / k, so that the grid still holds every multiple of DEFAULT_DT.
                fast = time_scales(model)[0]
                dt = DEFAULT_DT / max(1, math.ceil(DEFAULT_DT * DT_PER_SCALE / fast - 1e-9))
            self.dt = dt
            self._source.progress = progress
            self.t_complete = math.inf
            self.error_groups = 0  # no sampling error
        self.immediate_probability = self._source.immediate_probability
        self._cache: dict = {}

    def _gaussian(self, model, closure_variance, quadrature_nodes, x_points):
        owner = "CrossingEstimator"
        if model.linear_gaussian() is None:
            raise ParameterError(
                owner, "model",
                f"{type(model).__name__} has no linear-Gaussian description; pass a simulated "
                "ensemble (simulate(..., record_upcrossings=K)) for the empirical estimator",
            )  # fmt: skip
        lg = to_arrays(model).linear_gaussian()
        g, B = np.asarray(lg.crossing, float), np.asarray(lg.B, float)
        noise = float(g @ B @ B.T @ g)
        self.exact = bool(model.crossing_is_smooth) and noise == 0.0
        if self.exact:
            if closure_variance is not None:
                raise ParameterError(
                    owner,
                    "closure_variance",
                    "applies only when noise enters the crossing variable "
                    "(here the formulas are exact)",
                )
            cvar = 0.0
        elif closure_variance is None:
            cvar = noise
        else:
            cvar = check_positive(owner, "closure_variance", closure_variance)
        self.closure_variance = cvar
        # (`device_put`: `jnp.asarray` would compile a conversion per shape in each process)
        cr = G.Crossing(*jax.device_put(tuple(np.asarray(x, float) for x in (
            lg.A, lg.b, lg.B, lg.crossing, lg.position, self.level, cvar
        ))))  # fmt: skip
        return GaussianSource(
            cr, model.onset_mixture(quadrature_nodes),
            exact=self.exact, quadrature_nodes=quadrature_nodes, x_points=x_points,
        )  # fmt: skip

    @property
    def n_components(self) -> int:
        return self._source.n_components

    # -- upcrossing densities ------------------------------------------------------------------
    def _times(self, t, name, parameter="t"):
        t = _floats(name, parameter, t)
        if not np.all(np.isfinite(t)) or np.any(t < 0):
            raise ParameterError(name, parameter, "must be finite and >= 0")
        return t

    def _check_grid(self, owner, t_end, n_points=0):
        """Refuse, before it is allocated, a time grid (to `t_end` at the step `dt`, and the
        position boxes of `n_points` grid times) past `memory_limit()`: the grid holds per
        point the propagators (2 d^2 + d) and per component the moments, their midpoint
        moments and n1 (about 3 (d^2 + d + 2)); a box array is `(K, x_points, n)`, about
        eight of them at once."""
        if not isinstance(self._source, GaussianSource):
            return
        from .._memory import check_memory

        n = math.ceil(t_end / self.dt - 1e-9) + 1
        n_grid = max(8192, 1 << (n - 1).bit_length())  # (`GaussianSource.grid`'s length)
        d, K = len(self.model.state_names), self.n_components
        nbytes = 8.0 * n_grid * (2 * d * d + d + 3 * K * (d * d + d + 2))
        nbytes += 8.0 * 8 * K * self._settings["x_points"] * n_points
        fast = time_scales(self.model)[0]
        check_memory(
            owner,
            f"the time grid to t = {t_end:.4g} at dt = {self.dt:.3g} ({n_grid:.3g} points; "
            f"the model's fastest time scale is {fast:.3g})",
            nbytes,
            "pass a larger dt (the default is a fifth of the fastest time scale), a shorter "
            "horizon, or ask for shorter times",
        )

    def n1(self, t):
        """Upcrossing density $n_1(t)$ of the crossing variable through the stick level
        (eq. 13), for the slip process continued without absorption (mixed over the slipping
        onsets, so its weight is $1 - p_0$)."""
        t = self._times(t, "n1")
        if isinstance(self._source, EmpiricalSource):
            entry = self._source.grid(max(float(t.max(initial=0.0)), self.dt), self.dt)
            grid = np.arange(entry["n"]) * self.dt
            return np.interp(t, grid, self._source.w[0] * entry["n1"][0])
        return self._source.n1(t.ravel()).reshape(t.shape)

    def n1_joint(self, x, t):
        """$n_1(x, t)$ (eq. 11): density of an upcrossing at time `t` and position `x`, shape
        `(len(x), len(t))`. Empirical: a histogram on cells centred at evenly spaced x, t."""
        x = np.atleast_1d(_floats("n1_joint", "x", x))
        t = np.atleast_1d(self._times(t, "n1_joint"))
        src = self._source
        if isinstance(src, EmpiricalSource):
            ex, et = _edges(x, "x"), _edges(t, "t")
            H, _, _ = np.histogram2d(src.x, src.t, bins=(ex, et))
            return src.w[0] * H / (src.n_slip * np.diff(ex)[:, None] * np.diff(et)[None, :])
        return src.n1_joint(x, t)

    def n2(self, t1, t2):
        """Joint density $n_2(t_1, t_2)$ of upcrossings at two times, on the grid of all
        pairs: shape `(len(t1), len(t2))`, symmetric. On the diagonal: the limit
        $t_2 \\to t_1$, finite when `exact`, infinite for the white-noise closure."""
        t1 = np.atleast_1d(self._times(t1, "n2"))
        t2 = np.atleast_1d(self._times(t2, "n2"))
        if isinstance(self._source, EmpiricalSource):
            raise NotImplementedError(
                "n2 of simulated crossings is used through its integral in the series; "
                "point values are not estimated"
            )
        T1, T2 = np.meshgrid(t1, t2, indexing="ij")
        lo, lag = np.minimum(T1, T2).ravel(), np.abs(T2 - T1).ravel()
        diag = lag == 0
        lag = np.where(diag, 1e-7 * self.dt, lag)  # the diagonal as a limit
        out = self._source.n2(lo, lag)
        if not self.exact:
            out = np.where(diag, np.inf, out)
        return np.where(lo > 0, out, 0.0).reshape(T1.shape)

    def n2_integral(self, t):
        r"""$K(t) = \int_0^t n_2(t, s)\,ds$, the second-order term of the series (6)-(7)
        (mixed over the slipping onsets, as `n1`), on the grid of step `dt` and interpolated.
        Empirical: the upcrossings in each grid cell, each weighted by the number of earlier
        ones on its path, per path and unit time."""
        t = self._times(t, "n2_integral")
        t_end = self._grid_end(max(float(t.max(initial=0.0)), self.dt))
        self._check_grid("CrossingEstimator", t_end)
        entry = self._source.grid(t_end, self.dt)
        n = int(round(t_end / self.dt)) + 1
        K = self._source.w @ self._source.second_order(entry, n)
        return np.interp(t, np.arange(n) * self.dt, K)

    @property
    def stationary_rate(self) -> float:
        """The large-t limit of $n_1$ (for one slipping onset): the upcrossing rate of the
        stationary process. Exact case: Rice's
        $\\frac{1}{2\\pi}\\sqrt{\\lambda_2/\\lambda_0}\\,e^{-(v_b - \\bar v)^2/2\\lambda_0}$,
        $\\lambda_0 = \\mathrm{var}\\,v$, $\\lambda_2 = \\mathrm{var}\\,\\dot v$."""
        if isinstance(self._source, EmpiricalSource):
            raise NotImplementedError("the stationary rate needs the Gaussian description")
        return self._source.stationary_rate()

    # -- series on the grid ----------------------------------------------------------------------
    def _series(self, t_end, method, order, normalized):
        """The first-passage density on t_k = k dt up to t_end, and diagnostics; `info["mass"]`
        is its integral from 0 to each grid time, exact for first order (the integral of n1
        is error-controlled, `GaussianSource._cell_integrals`), and the second order's own
        integrals by the trapezoid rule on the grid."""
        key = ("series", method, order, normalized, t_end)
        if key in self._cache:
            return self._cache[key]
        self._check_grid("CrossingEstimator", t_end)
        h, src = self.dt, self._source
        entry = src.grid(t_end, h)
        n = int(round(t_end / h)) + 1
        second = src.second_order(entry, n) if order == 2 else None
        n1, K, w, I1 = self._mixed(entry["n1"][:, :n], second, entry["I1"][:, :n])
        if K is None:
            K = np.zeros_like(n1)
        F, mass = np.zeros(n), np.zeros(n)
        info = {"escape_rate_min": math.inf, "t_n": None, "unresolved": entry["unresolved"]}
        for c in range(n1.shape[0]):
            if method == "truncation":
                Fc = series.truncation(n1[c], K[c], order)
                massc = I1[c] - (series.cumulative(K[c], h) if order == 2 else 0.0)
            else:
                Fc, rate = series.decoupling(n1[c], K[c], order, h, I1=I1[c])
                S = I1[c]
                if order == 2:
                    S = I1[c] - series.cumulative(K[c] - n1[c] * I1[c], h)
                massc = -np.expm1(-S)  # F = Sdot exp(-S) integrates to 1 - exp(-S)
                if n > 1:
                    info["escape_rate_min"] = min(info["escape_rate_min"], float(rate[1:].min()))
            F += w[c] * Fc
            mass += w[c] * massc
        if normalized:
            total = src.w.sum()
            F, k = series.normalise_truncation(
                F / max(total, 1e-300), h, integral=mass / max(total, 1e-300)
            )
            F *= total
            info["t_n"] = None if k is None else k * h
            if k is not None:
                mass = np.minimum(mass, mass[k])
        info["mass"] = mass
        # How well the grid resolves n1: its trapezoid integral against the error-controlled
        # one (what second-order integrals on the grid can be trusted to).
        exact_I1 = float(w @ I1[:, -1])
        trap_I1 = float(w @ series.cumulative(n1, h)[:, -1])
        info["grid_gap"] = abs(trap_I1 - exact_I1) / max(abs(exact_I1), 1e-300)
        out = (np.arange(n) * h, F, info)
        self._cache[key] = out
        return out

    def _mixed(self, n1, K, I1=None):
        """n1, K and the integral I1 of n1 per component with their weights, or
        (mixing='process') those of the mixture process: averaged over the slipping onsets,
        with their total weight."""
        w = self._source.w
        if self.mixing == "components" or n1.shape[0] == 1:
            return n1, K, w, I1
        total = w.sum()
        avg = lambda a: None if a is None else (w @ a / total)[None]
        return avg(n1), avg(K), np.array([total]), avg(I1)

    def first_passage(
        self, t, method: str = "decoupling", order: int = 1, normalized: bool = False
    ):
        r"""First-passage (slip-time) density $\mathcal F(t)$ by a level-crossing approximation.

        - `method="truncation"`: partial sums $\mathcal F_n^{(k)}$ of eq. (6); with
          `normalized=True`, cut where the integral reaches 1 ($\hat{\mathcal F}_n^{(k)}$;
          the paper prints $\Theta(t - t_n)$ where $\Theta(t_n - t)$ is meant).
        - `method="decoupling"`: cumulant approximations $\mathcal F_g^{(k)}$ (eq. 7).

        `order` is 1 or 2. Computed on a grid of step `dt` and interpolated. A density or
        escape rate that goes negative is returned as is, with an `ApproximationWarning`
        that says where; so is a normalised truncation that never reaches 1.
        """
        self._check(method, order, normalized)
        t = self._times(t, "first_passage")
        if t.size == 0:
            return t.copy()
        t_end = self._grid_end(float(t.max()))
        grid, F, info = self._series(t_end, method, order, normalized)
        self._report(grid, F, info, method, order, normalized)
        if order == 1 and isinstance(self._source, GaussianSource):
            out = self._first_order_at(t.ravel(), t_end, method).reshape(t.shape)
            if normalized and info["t_n"] is not None:
                out = np.where(t <= info["t_n"], out, 0.0)
            return out
        return np.interp(t, grid, F)

    def _first_order_at(self, t, t_end, method):
        """First-order densities at the times `t` themselves (no grid interpolation): n1(t),
        and for decoupling n1(t) exp(-int_0^t n1), the integral error-controlled (an onset
        transient shorter than dt is resolved where it is asked for)."""
        src = self._source
        entry = src.grid(t_end, self.dt)
        n1c = np.atleast_2d(src._n1_at(t))  # (K, m)
        if method == "truncation":
            return src.w @ n1c
        I1c = src.I1_at(t, entry)
        if self.mixing == "process" and src.n_components > 1:
            total = src.w.sum()
            return (src.w @ n1c) * np.exp(-(src.w @ I1c) / total)
        return src.w @ (n1c * np.exp(-I1c))

    slip_time_density = first_passage

    def quadrature_error(
        self, kind: str, x, method: str = "decoupling", order: int = 1, normalized=False
    ) -> float:
        """How far a density moves when the onset quadrature's nodes are doubled (a random
        threshold's Gauss-Hermite rule, a random initial rate's Gauss-Legendre rule): the L1
        distance, over cells, between this estimator's density and that of a twin with
        twice `quadrature_nodes` (and the same settings otherwise), an estimate of this
        one's quadrature error. `kind`: `"slip_time"` (`x`: cell edges), `"period"` or
        `"slip_distance"` (`x`: evenly spaced cell centres). 0 for a single Gaussian onset
        and for the empirical estimator (no quadrature)."""
        if not isinstance(self._source, GaussianSource) or self.n_components == 1:
            return 0.0
        if self._twin is None:
            self._twin = CrossingEstimator(
                self.model, quadrature_nodes=2 * self.quadrature_nodes, **self._settings
            )
        args = (method, order, normalized)
        x = _floats("quadrature_error", "x", x)
        with collecting_notes():  # (the twin's notes are the estimate's own: not repeated)
            if kind == "slip_time":
                a = self.first_passage_cells(x, *args)
                b = self._twin.first_passage_cells(x, *args)
                return float(np.sum(np.abs(a - b) * np.diff(x)))
            if kind == "period":
                a, b = self.period_density(x, *args), self._twin.period_density(x, *args)
            elif kind == "slip_distance":
                a = self.slip_distance_density(x, *args)
                b = self._twin.slip_distance_density(x, *args)
            else:
                raise ParameterError(
                    "quadrature_error", "kind", "must be slip_time, period or slip_distance", kind
                )
        width = float(x[1] - x[0]) if x.size > 1 else 1.0
        return float(np.sum(np.abs(a - b)) * width)

    def first_passage_cells(
        self, edges, method: str = "decoupling", order: int = 1, normalized: bool = False
    ):
        r"""Averages of `first_passage` over the cells between consecutive `edges` (to
        compare with a histogram). First order with the exact Gaussian formulas: exact, from
        the closed-form antiderivatives ($\int n_1 = I_1$, $\int n_1 e^{-I_1} =
        -e^{-I_1}$) at the edges alone; otherwise the midpoint rule on points at most
        `dt / 4` apart (the density rises from 0 to its peak within a few hundredths of a
        time unit after onset)."""
        self._check(method, order, normalized)
        edges = self._times(edges, "first_passage_cells", "edges")
        if edges.ndim != 1 or edges.size < 2 or np.any(np.diff(edges) <= 0):
            raise ParameterError(
                "first_passage_cells", "edges", "must be an increasing 1-d array of >= 2 times"
            )
        if order != 1 or not isinstance(self._source, GaussianSource):
            args = (method, order, normalized)
            return cell_average(lambda t: self.first_passage(t, *args), edges, self.dt / 4)
        t_end = self._grid_end(float(edges[-1]))
        grid, F, info = self._series(t_end, method, order, normalized)
        self._report(grid, F, info, method, order, normalized)
        src = self._source
        ends = edges
        if normalized and info["t_n"] is not None:
            ends = np.minimum(edges, info["t_n"])
        I1 = np.atleast_2d(src.I1_at(ends, src.grid(t_end, self.dt)))  # (K, m + 1)
        width = np.diff(edges)
        if method == "truncation":
            return (src.w @ np.diff(I1, axis=1)) / width
        if self.mixing == "process" and src.n_components > 1:
            total = src.w.sum()
            S = np.exp(-(src.w @ I1) / total)
            return total * (S[:-1] - S[1:]) / width
        S = np.exp(-I1)
        return (src.w @ (S[:, :-1] - S[:, 1:])) / width

    def _grid_end(self, t_max):
        t_end = self.dt * math.ceil(max(t_max, self.dt) / self.dt - 1e-9)
        if t_end > self.t_complete:
            note(
                f"the recorded upcrossings are complete only up to t = {self.t_complete:.4g} "
                f"(some paths reached the cap); estimates beyond it are biased low",
                ApproximationWarning,
                stacklevel=3,
            )
        return t_end

    def _report(self, grid, F, info, method, order, normalized):
        name = f"{method} order {order}"
        scale = max(1.0, float(np.max(np.abs(F)))) if F.size else 1.0
        neg = F < -1e-12 * scale
        if neg.any():
            note(
                f"{name}: density negative on t in [{grid[neg][0]:.4g}, {grid[neg][-1]:.4g}] "
                f"(min {F.min():.4g}); returned unclipped",
                ApproximationWarning,
                stacklevel=3,
            )
        if method == "decoupling" and info["escape_rate_min"] < 0:
            note(
                f"{name}: negative escape rate (min {info['escape_rate_min']:.4g}); the "
                "approximation is not a density there",
                ApproximationWarning,
                stacklevel=3,
            )
        total = float(self._source.w.sum())
        if method == "truncation" and not normalized and info["mass"][-1] > total + MASS_TOL:
            note(
                f"{name}: integrates to {float(info['mass'][-1]):.4g} by t = {grid[-1]:.4g}, "
                f"more than the {total:.4g} of slipping paths: a truncation counts later "
                "upcrossings too",
                ApproximationWarning,
                stacklevel=3,
            )
        if order == 2 and info.get("grid_gap", 0.0) > MASS_TOL:
            note(
                f"{name}: dt = {self.dt:g} does not resolve n1's onset transient (the trapezoid "
                f"rule misses its integral by {info['grid_gap']:.2g} relative); the second-order "
                "integrals on this grid are as coarse: take a shorter dt",
                ApproximationWarning,
                stacklevel=3,
            )
        if normalized and info["t_n"] is None:
            mass = float(info["mass"][-1])
            note(
                f"normalised truncation (order {order}): the density integrates to only "
                f"{mass:.4g} by t = {grid[-1]:.4g}, so it is not cut",
                ApproximationWarning,
                stacklevel=3,
            )

    def diagnostics(self, t_max: float, method="decoupling", order=1, normalized=False) -> dict:
        """Validity checks of one approximation on [0, t_max]: its mass, most negative
        value, lowest escape rate (decoupling) and the cut time t_n (normalised truncation)."""
        self._check(method, order, normalized)
        t_max = check_positive("diagnostics", "t_max", t_max)
        grid, F, info = self._series(self._grid_end(t_max), method, order, normalized)
        return dict(
            mass=float(info["mass"][-1]),
            min_density=float(F.min()),
            escape_rate_min=info["escape_rate_min"],
            t_n=info["t_n"],
        )

    # -- position-resolved densities (eqs. 2 and 4) ---------------------------------------------
    def _horizon(self):
        """End of the time grid for position-resolved densities: given, or where the
        first-order survival exp(-int n1) falls below 1e-4 (at most 1000)."""
        if self.horizon is not None:
            return self.horizon
        if isinstance(self._source, EmpiricalSource):
            return min(self._source.t_max, self._source.t_complete)
        t_end = 8.0
        while t_end < 1000.0:
            _, _, info = self._series(self._grid_end(t_end), "decoupling", 1, False)
            if info["mass"][-1] > (1 - 1e-4) * self._source.w.sum():
                return t_end
            t_end *= 2
        return t_end

    def _points(self, method, order, normalized, t_stop=None):
        """Point masses of F(x, t) dx dt: times, positions and masses (K, P). All grid
        times up to the horizon, or (exact sources) only those that can fall before
        `t_stop`: grid time t_k stands for [t_k - h/2, t_k + h/2], and the masses at t_k
        depend on the series up to t_k alone."""
        t_end = self._grid_end(self._horizon())
        h, src = self.dt, self._source
        n = int(round(t_end / h)) + 1
        if t_stop is not None and isinstance(src, GaussianSource):
            n = min(n, max(2, int(math.floor(t_stop / h + 0.5)) + 2))
        key = ("points", method, order, normalized, t_end)
        have = self._cache.get(key)
        if have is None or have[0] < n:
            have = (n, self._masses(method, order, normalized, t_end, n))
            self._cache[key] = have
        T, X, W, mass, X0 = have[1]
        if have[0] > n:  # a longer prefix is at hand: time is the last axis
            T, X, W, mass = (a[..., :n] for a in (T, X, W, mass))
        return T, X, W, mass, X0

    def _masses(self, method, order, normalized, t_end, n):
        """`_points` over the first n grid times."""
        self._check_grid("CrossingEstimator", t_end, n)
        h, src = self.dt, self._source
        coarse = self.joint_dt or max(h, t_end / 300)
        T, X, W, n1w, K2w, X0 = src.points(t_end, h, order, coarse, n)
        entry = src.grid(t_end, h)
        n = T.shape[-1] if isinstance(src, GaussianSource) else int(round(t_end / h)) + 1
        grid = np.arange(n) * h
        n1 = entry["n1"][:, :n]
        K = src.second_order(entry, n) if order == 2 else np.zeros_like(n1)
        I1 = entry["I1"][:, :n]
        cells = np.diff(I1, axis=1)  # error-controlled integrals of n1 over the grid cells
        if self.mixing == "process" and n1.shape[0] > 1:
            # every component sees the mixture process's exponent (and truncation cut)
            mix_n1, mix_K, _, mix_I1 = self._mixed(n1, K, I1)
            n1 = np.repeat(mix_n1, src.n_components, axis=0)
            K = np.repeat(mix_K, src.n_components, axis=0)
            I1 = np.repeat(mix_I1, src.n_components, axis=0)
        mass = np.zeros_like(n1w)
        if isinstance(src, GaussianSource):  # the boxes sit at the grid times themselves
            at_times = lambda Tc, f: f[:n]
        else:
            at_times = lambda Tc, f: np.interp(Tc, grid, f)

        def window(per_cell):
            """Per grid time, the mass of its window [t_k - h/2, t_k + h/2] from the masses
            of the cells on either side (half of each; the grid's end has one). Time 0 has
            no boxes (n1 = 0 there): its half of the first cell goes to the next time."""
            out = np.zeros(per_cell.shape[:-1] + (per_cell.shape[-1] + 1,))
            out[..., :-1] += 0.5 * per_cell
            out[..., 1:] += 0.5 * per_cell
            out[..., 1] += out[..., 0]
            out[..., 0] = 0.0
            return out

        def rescaled(boxes, target):
            """The boxes of each grid time, spread over positions as they are, carrying
            `target` in all (a first-order mass known exactly; the boxes' own time weights
            are the trapezoid rule's, which misses an onset transient shorter than dt)."""
            total = boxes.sum(axis=0)
            return boxes * np.where(total > 0, target / np.where(total > 0, total, 1.0), 0.0)

        exact_boxes = isinstance(src, GaussianSource) and order == 1
        for c in range(src.n_components):
            Tc = T[c]
            if method == "truncation":
                if exact_boxes:
                    mass[c] = rescaled(n1w[c], window(cells[c])[:n])
                else:
                    mass[c] = n1w[c] if order == 1 else n1w[c] - K2w[c]
                if normalized:
                    marg = series.truncation(n1[c], K[c], order)
                    cum = I1[c] - (series.cumulative(K[c], h) if order == 2 else 0.0)
                    _, k = series.normalise_truncation(marg, h, integral=cum)
                    if k is not None:
                        mass[c] = np.where(Tc <= grid[k] + 0.5 * h, mass[c], 0.0)
            elif order == 1:
                if exact_boxes:
                    # F = n1 exp(-I1): a cell's mass is exp(-I1(t_k)) - exp(-I1(t_k+1)) when
                    # the component's own n1 is the exponent's; else n1's cell integral
                    # times exp(-I1) at the grid time
                    if self.mixing == "process" and src.n_components > 1:
                        target = window(cells[c])[:n] * np.exp(-I1[c])
                    else:
                        target = window(-np.diff(np.exp(-I1[c])))[:n]
                    mass[c] = rescaled(n1w[c], target)
                else:
                    mass[c] = n1w[c] * np.exp(-at_times(Tc, I1[c]))
            else:
                G_ = K[c] - n1[c] * I1[c]
                S = I1[c] - series.cumulative(G_, h)
                n1b = n1w[c]
                if isinstance(src, GaussianSource):  # n1's own boxes, as at first order
                    n1b = rescaled(n1w[c], window(np.diff(entry["I1"][c, :n]))[:n])
                rate = n1b - (K2w[c] - n1b * at_times(Tc, I1[c]))
                mass[c] = rate * np.exp(-at_times(Tc, S))
            mass[c] *= src.w[c]
        return T, X, W, mass, X0

    def slip_distance_density(self, d, method="decoupling", order=1, normalized=False):
        r"""Density of the slip distance $d = x_0 - x_{sl}$ (eq. 4),
        $p(d) = \int_0^\infty \mathcal F(x_0 - d, t)\,dt$, over $t \le$ `horizon`.

        `d` must be evenly spaced: each value is the density averaged over the cell of width
        $\Delta d$ centred on it, as a histogram on those cells would give."""
        return self._histogram(d, "slip_distance", method, order, normalized)

    def period_density(self, T, method="decoupling", order=1, normalized=False):
        r"""Density of the period $T = T_{sl} + T_{st}$ (eq. 2), with the stick time
        $T_{st} = \max(0, (x_0' - x_{sl})/v_b)$: eq. (2) integrates over the sticks behind the
        threshold; the sticks beyond it release at once ($T = T_{sl}$), a term the paper
        leaves out, so that here $p(T)$ has the mass of $\mathcal F$. $x_0'$ is the next
        cycle's threshold: the same $x_0$ for a fixed threshold; drawn independently from
        the threshold law for a random one (the density is averaged over that law).

        `T` must be evenly spaced: cell averages, as for `slip_distance_density`."""
        return self._histogram(T, "period", method, order, normalized)

    def _histogram(self, points, kind, method, order, normalized):
        self._check(method, order, normalized)
        points = _floats(kind, kind, points)
        edges = _edges(np.atleast_1d(points), kind)
        # a period is at least the slip time: later grid times cannot reach the cells
        t_stop = edges[-1] if kind == "period" else None
        T, X, W, all_mass, X0 = self._points(method, order, normalized, t_stop)
        nodes, weights = self._source.thresholds
        shape = all_mass.shape
        # Boxes below 1e-14 / N of the total mass of the N are left out (together they move
        # no cell by 1e-14 of it; with a random threshold they are about half of them: the
        # tails of the position grid, the components of the law's outer nodes). The cells
        # are sums over boxes: a few components at a time, ~1e6 boxes stay in the cache.
        floor = 1e-14 * np.abs(all_mass).sum() / max(all_mass.size, 1)
        step = max(1, 1_000_000 // max(1, math.prod(shape[1:])))
        cells = np.zeros(edges.size - 1)
        for first in range(0, shape[0], step):
            part = slice(first, first + step)
            keep = np.abs(all_mass[part]) > floor
            T_, X_, W_, x0 = (np.broadcast_to(a, shape)[part][keep] for a in (T, X, W, X0))
            mass = all_mass[part][keep]
            if kind == "slip_distance":
                lo, hi = x0 - X_ - W_ / 2, x0 - X_ + W_ / 2
                cells += _deposit(edges, *_within(edges, lo, hi, mass))
            elif nodes.size == 1:  # fixed threshold: each component's own onset position
                cells += self._fixed_threshold_periods(edges, T_, X_, W_, x0, mass)
            else:  # the next threshold is independent of this cycle
                cells += self._random_threshold_periods(edges, T_, X_, W_, mass, nodes, weights)
        out = cells / np.diff(edges)
        name = f"{method} order {order}"
        if (out < 0).any():
            note(
                f"{name}: {kind} density negative in places "
                f"(min {out.min():.4g}); returned unclipped",
                ApproximationWarning,
                stacklevel=3,
            )
        self._check_mass(name, kind, edges, cells, all_mass, t_stop, method, order, normalized)
        return out.reshape(points.shape)

    def _check_mass(self, name, kind, edges, cells, all_mass, t_stop, method, order, normalized):
        """Warn, with the numbers, where a position-resolved density does not carry what it
        must (by more than `MASS_TOL`): what the cells hold against what the boxes carry
        (the grid misses part of the support), and against the slip-time series' own mass
        (the time grid does not resolve the second-order integrals), and a truncation that
        carries more than the slipping paths (it counts later upcrossings)."""
        carried, held = float(all_mass.sum()), float(cells.sum())
        if carried - held > MASS_TOL:
            note(
                f"{name}: the {kind} cells [{edges[0]:.4g}, {edges[-1]:.4g}] hold {held:.4g} "
                f"of the {carried:.4g} it carries: widen them",
                ApproximationWarning,
                stacklevel=4,
            )
        if t_stop is None and isinstance(self._source, GaussianSource):
            expected = float(self._series(self._grid_end(self._horizon()), method, order,
                                          normalized)[2]["mass"][-1])  # fmt: skip
            if abs(carried - expected) > MASS_TOL:
                note(
                    f"{name}: the {kind} density carries {carried:.4g}, the slip-time density "
                    f"{expected:.4g}: dt = {self.dt:g} does not resolve its second-order "
                    "integrals (a shorter dt does)",
                    ApproximationWarning,
                    stacklevel=4,
                )
        total = float(self._source.w.sum())
        if method == "truncation" and carried > total + MASS_TOL:
            note(
                f"{name}: the {kind} density carries {carried:.4g}, more than the "
                f"{total:.4g} of slipping paths: a truncation counts later upcrossings too",
                ApproximationWarning,
                stacklevel=4,
            )

    def _half(self):
        """Half the time cell a grid time stands for (exact sources; simulated upcrossings
        carry their own times)."""
        return 0.5 * self.dt if isinstance(self._source, GaussianSource) else 0.0

    def _fixed_threshold_periods(self, edges, T, X, W, x0, mass):
        """Period cells for T = t + max(0, x0 - x) / v_b, boxes in x: the part of a box at
        x >= x0 sticks at T = t. Each grid time stands for [t - h/2, t + h/2] (its
        trapezoid cell): spread it over that, or whole rows of mass would fall on one side
        of a cell edge."""
        half = self._half()
        lo, hi = x0 - X - W / 2, x0 - X + W / 2
        span = np.where(hi > lo, hi - lo, 1.0)
        neg = np.where(hi > lo, np.clip(-lo, 0.0, span) / span, (hi <= 0).astype(float))
        a = T + np.maximum(lo, 0.0) / self.level
        b = T + np.maximum(hi, 0.0) / self.level
        cells = _deposit(edges, *_within(edges, T - half, T + half, mass * neg))
        return cells + _deposit(edges, *_within(edges, a - half, b + half, mass * (1 - neg)))

    def _random_threshold_periods(self, edges, T, X, W, mass, nodes, weights):
        """Period cells for T = t + max(0, x0' - x) / v_b with x0' independent of (t, x) and
        drawn from the discrete law (nodes, weights): the cells of
        `_fixed_threshold_periods` averaged over the nodes, without a pass per node.

        For node x0' a box [lo, hi] in x is either above it (lo >= x0': T = t), below it
        (hi <= x0': T from t + (x0' - hi) / v_b to t + (x0' - lo) / v_b, i.e. y + x0' / v_b
        with y in [t - hi / v_b, t - lo / v_b]) or straddles it. The boxes above add their
        mass times the weight of the nodes below them at T = t; those below a node add
        their cells in y shifted by x0' / v_b: grouped by the first node above them, each
        group's cumulative mass in y is evaluated at the cell edges shifted back for every
        node of the group and above. The few straddling (box, node) pairs are deposited as
        `_fixed_threshold_periods` does."""
        half, vb = self._half(), self.level
        order = np.argsort(nodes)
        nodes, weights = nodes[order], weights[order]
        lo, hi = X - W / 2, X + W / 2
        below_lo = np.searchsorted(nodes, lo, side="right")  # nodes x0' <= lo
        below_hi = np.searchsorted(nodes, hi, side="left")  # nodes x0' < hi
        points = hi <= lo
        below_hi = np.where(points, below_lo, below_hi)  # a point at x: x0' <= x sticks at t
        cum_w = np.concatenate([[0.0], np.cumsum(weights)])
        # at T = t: every box, weighted by the nodes it lies wholly above
        cells = _deposit(edges, *_within(edges, T - half, T + half, mass * cum_w[below_lo]))
        # straddled nodes (lo < x0' < hi), one (box, node) pair each
        n_in = below_hi - below_lo
        if n_in.any():
            box = np.repeat(np.arange(T.size), n_in)
            node = below_lo[box] + (np.arange(box.size) - np.repeat(np.cumsum(n_in) - n_in, n_in))
            x0, w = nodes[node], weights[node] * mass[box]
            span = hi[box] - lo[box]
            up = (hi[box] - x0) / span  # the share above x0': T = t
            t = T[box]
            cells += _deposit(edges, *_within(edges, t - half, t + half, w * up))
            b = t + (x0 - lo[box]) / vb
            cells += _deposit(edges, *_within(edges, t - half, b + half, w * (1 - up)))
        # wholly below nodes below_hi, below_hi + 1, ...: in y = t - x / v_b
        y_lo, y_hi = T - hi / vb - half, T - lo / vb + half
        order = np.argsort(below_hi, kind="stable")
        bounds = np.searchsorted(below_hi[order], np.arange(nodes.size + 1))
        y_lo, y_hi, mass = y_lo[order], y_hi[order], mass[order]
        cum = np.zeros(edges.size)
        for r in range(nodes.size):
            group = slice(bounds[r], bounds[r + 1])
            if bounds[r + 1] == bounds[r]:
                continue
            shift = nodes[r:] / vb  # (nodes above the group)
            queries = (edges[None, :] - shift[:, None]).ravel()
            at = np.argsort(queries)
            Y = np.empty(queries.size)
            # the boxes are at least 2 half = h wide: slopes and intercepts (`_cumulative`)
            wide = 0 if half > 0 else 2
            Y[at] = _cumulative(queries[at], y_lo[group], y_hi[group], mass[group], wide)
            cum += weights[r:] @ Y.reshape(shift.size, edges.size)
        return cells + np.diff(cum)

    # -- sampling errors (empirical estimator) ---------------------------------------------
    def n1_se(self, t):
        """Standard error of `n1(t)` (see `_sampling_error`)."""
        return self._sampling_error("n1", t)

    def n2_integral_se(self, t):
        """Standard error of `n2_integral(t)`."""
        return self._sampling_error("n2_integral", t)

    def first_passage_se(self, t, method="decoupling", order=1, normalized=False):
        """Standard error of `first_passage(t, method, order, normalized)`."""
        return self._sampling_error("first_passage", t, method, order, normalized)

    def first_passage_cells_se(self, edges, method="decoupling", order=1, normalized=False):
        """Standard error of `first_passage_cells(edges, method, order, normalized)`."""
        return self._sampling_error("first_passage_cells", edges, method, order, normalized)

    def slip_distance_density_se(self, d, method="decoupling", order=1, normalized=False):
        """Standard error of `slip_distance_density(d, method, order, normalized)`."""
        return self._sampling_error("slip_distance_density", d, method, order, normalized)

    def period_density_se(self, T, method="decoupling", order=1, normalized=False):
        """Standard error of `period_density(T, method, order, normalized)`."""
        return self._sampling_error("period_density", T, method, order, normalized)

    def _sampling_error(self, name, *args):
        r"""Standard error of the estimate `name(*args)` over the simulated paths, by a
        delete-a-group jackknife: the paths are dealt into $B$ = `error_groups` groups
        (path $i$ to group $i \bmod B$), the estimate is recomputed without each group,
        $\hat\theta_{(b)}$, and $\mathrm{se}^2 = \frac{B-1}{B}\sum_b
        (\hat\theta_{(b)} - \bar\theta)^2$. For a statistic linear in the paths ($n_1$,
        $K$, the truncations) this is exactly the batch-means error; for the nonlinear ones
        (decoupling, the normalised cut) every recomputation keeps $(B-1)/B$ of the paths,
        so it carries the full estimate's nonlinearity, not that of a small batch. A 95 %
        band is $\pm t_{0.975,\,B-1}\,\mathrm{se}$. The paths must be independent (those of
        `simulate`; windows of one long chain run are not). The exact formulas have no
        sampling error: zeros."""
        method = getattr(self, name)
        if not isinstance(self._source, EmpiricalSource):
            with collecting_notes():  # (its notes are the estimate's own: not repeated)
                return np.zeros(np.shape(method(*args)))
        up, B = self._upcrossings, self.error_groups
        group = np.arange(up.n_paths) % B
        horizon = self._horizon()
        values = []
        with collecting_notes():
            # the estimate itself reports its warnings; B near-copies of them add nothing
            for b in range(B):
                keep = group != b
                part = dataclasses.replace(up, **{f: getattr(up, f)[keep] for f in up.PER_PATH})
                sub = CrossingEstimator(
                    self.model, part, dt=self.dt, horizon=horizon, joint_dt=self.joint_dt,
                    mixing=self.mixing, x_points=self._settings["x_points"],
                )  # fmt: skip
                values.append(np.asarray(getattr(sub, name)(*args), float))
        values = np.array(values)
        spread = np.sum((values - values.mean(axis=0)) ** 2, axis=0)
        return np.sqrt((B - 1) / B * spread)

    def _check(self, method, order, normalized):
        check_choice("first_passage", "method", method, METHODS)
        if order not in (1, 2):
            raise ParameterError("first_passage", "order", "must be 1 or 2", order)
        if normalized and method != "truncation":
            raise ParameterError(
                "first_passage", "normalized", "applies to method='truncation' only", normalized
            )


def _deposit(edges, lo, hi, mass):
    """Mass of uniform boxes [lo, hi] (points where lo == hi) falling in each cell of
    `edges`."""
    return np.diff(_cumulative(edges, lo, hi, mass))


def _cumulative(at, lo, hi, mass, pairwise=2):
    """Mass of uniform boxes [lo, hi] (points where lo == hi) at or below each value of
    `at` (increasing). For a few values (cell edges) the boxes are not sorted: a box adds
    its whole mass from the first value >= hi on (binary search in `at`) and, at the values
    inside it, a share linear in the value: pair by pair for a box holding up to
    `pairwise` values, else as a slope and an intercept summed over the boxes that hold
    each value (a box holding three values is two value spacings wide, so its slope is
    bounded and the sums keep their precision; `pairwise=0` where every box is known to be
    wide). For many values and boxes of any width, `_cumulative_sorted`."""
    n_at = at.size
    if n_at > 256 and pairwise:
        return _cumulative_sorted(at, lo, hi, mass)
    box = hi > lo
    inside = np.searchsorted(at, lo, side="right")  # first value > lo
    whole = np.where(box, np.searchsorted(at, hi, side="left"), np.searchsorted(at, lo))
    out = np.cumsum(np.bincount(whole, weights=mass, minlength=n_at + 1)[:n_at])
    span = np.where(box, whole - inside, 0)
    few = (span > 0) & (span <= pairwise)
    if few.any():
        (which,) = np.nonzero(few)
        span_f = span[which]
        i = np.repeat(which, span_f)
        q = np.repeat(inside[which] - np.cumsum(span_f) + span_f, span_f) + np.arange(i.size)
        share = (at[q] - lo[i]) / (hi[i] - lo[i])
        out += np.bincount(q, weights=mass[i] * share, minlength=n_at)
    many = span > pairwise
    if many.any():
        slope = mass[many] / (hi[many] - lo[many])
        a, b = inside[many], whole[many]

        def summed(w):
            return np.cumsum(np.bincount(a, w, n_at + 1) - np.bincount(b, w, n_at + 1))[:n_at]

        out += summed(slope) * at + summed(-slope * lo[many])
    return out


def _cumulative_sorted(at, lo, hi, mass):
    """`_cumulative` through sorted breakpoints: a sum of ramps (boxes) and steps
    (points)."""
    box = hi > lo
    density = np.where(box, mass / np.where(box, hi - lo, 1.0), 0.0)
    # sum_i density_i ((e - lo_i)^+ - (e - hi_i)^+): breakpoints with slopes +-density
    p = np.concatenate([lo[box], hi[box]])
    c = np.concatenate([density[box], -density[box]])
    order = np.argsort(p)
    p, c = p[order], c[order]
    cum_c, cum_cp = np.concatenate([[0], np.cumsum(c)]), np.concatenate([[0], np.cumsum(c * p)])
    k = np.searchsorted(p, at, side="right")
    ramps = cum_c[k] * at - cum_cp[k]
    pts = np.sort(lo[~box])
    w = mass[~box][np.argsort(lo[~box])]
    steps = np.concatenate([[0], np.cumsum(w)])[np.searchsorted(pts, at, side="right")]
    return ramps + steps


def _within(edges, lo, hi, mass):
    """The boxes that can change the cells of `edges`: a box wholly above the last edge
    adds nothing, one wholly below the first adds the same to every cumulative value."""
    keep = (hi >= edges[0]) & (lo <= edges[-1]) & (mass != 0)
    return lo[keep], hi[keep], mass[keep]


def _floats(owner, parameter, values):
    """`values` (real numbers: not strings, booleans or objects) as a float array, or a
    `ParameterError`."""
    try:
        arr = np.asarray(values)
    except (TypeError, ValueError):  # ragged nestings
        arr = np.asarray(None)
    if arr.dtype.kind not in "iuf":
        short = isinstance(values, (str, int, float)) and len(repr(values)) <= 40
        raise ParameterError(
            owner,
            parameter,
            f"must be a real number or an array of them, not {type(values).__name__}",
            values if short else None,
        )
    return arr.astype(float)


def _edges(points, name):
    """Cell edges around evenly spaced points."""
    if not np.all(np.isfinite(points)):
        raise ParameterError(name, name, "must be finite")
    if points.size < 2:
        raise ParameterError(name, name, "needs at least 2 evenly spaced values")
    step = points[1] - points[0]
    if step <= 0 or not np.allclose(np.diff(points), step, rtol=1e-6, atol=0):
        raise ParameterError(name, name, "must be evenly spaced and increasing")
    return np.append(points - step / 2, points[-1] + step / 2)
