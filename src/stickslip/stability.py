r"""Where each method fails: the noise-free slip, the critical driving speed, and a record
of the validity checks of every level-crossing approximation at one parameter point.

- `deterministic_slip(model)`: the slip time of the noise-free slip (the mean path of the
  model's linear-Gaussian description; noise is additive and zero-mean, so the mean is the
  $D = 0$ solution).
- `critical_speed(model)`: the driving speed above which the noise-free slip never returns
  to the stick level (stick-slip gives way to steady sliding).
- `stability_report(model)`: per method, the reasons it fails at this point (a negative or
  unnormalised density, a negative escape rate, a truncation that never normalises, the
  white-noise closure and the Monte Carlo that does not converge in dt) and the dynamical
  regime (stick-slip, multiperiodic, sliding).

`benchmarks/stability_map.py` draws these over a grid of driving speeds and noise levels.
"""

from __future__ import annotations

import dataclasses
import math
from types import MappingProxyType
from typing import Any

import numpy as np
from scipy import linalg, optimize

from ._errors import ParameterError, check_int, check_positive
from ._model import CreepingSlider, FrictionModel, time_scales

# -- thresholds ------------------------------------------------------------------------------
# A density below -NEGATIVE_TOL x its peak is a sign change of the approximation: rounding
# and quadrature noise is ~1e-12 of the peak (measured where the truncation is positive, D =
# 1e-4), while a failing truncation dips by percents; dips under 1e-3 (seen in far tails)
# are invisible on a plot and move the mass by less than 1e-3.
NEGATIVE_TOL = 1e-3
# Largest accepted error of an approximation's mass on [0, t_max] (the probability that the
# slip ends there): 5 %, an error that shows at a glance on a histogram of slip times and
# is well above the estimator's own grid error at DIAGNOSTICS_DT (below).
MASS_TOL = 0.05
# A slip that misses its first stick opportunity runs about one more oscillation: the period
# law gets a second peak. Above 5 % of the mass that peak is plain on a histogram, and the
# motion is called multiperiodic.
MULTIPERIODIC_P_MISS = 0.05
# z-value of the Monte Carlo sampling error added to MASS_TOL (the convention of the tests).
Z_SAMPLING = 4.0
# Time step of the estimator behind a report: DIAGNOSTICS_DT, or a fifth of the model's
# fastest time scale 1/max|eig(A)| where that is shorter (the onset transient of n1 lasts
# about the noise's correlation time; the second-order integrals are on this grid, the
# first-order masses are error-controlled whatever the grid). The second order costs
# (t_max / dt)^2; dt = 0.02 halves it against the default 0.01 and moves the masses by
# < 2e-3 (decoupling) and < 2 % of their size (truncations) on the public reference set.
DIAGNOSTICS_DT = 0.02
DIAGNOSTICS_PER_SCALE = 5.0
# Step of the Monte Carlo behind a report, in units of the slow time scale 1/min|eig(A)|:
# exact stepping is exact in law at any step (docs/simulator.md); 0.1 keeps the stick
# times' grid fine for the window test at no cost in accuracy.
MONTE_CARLO_STEP = 0.1
# Where no envelope bound applies, the noise-free path is followed until its slowest mode has
# decayed by e^-60 (a return after that would need a level within 1e-26 of the
# equilibrium), on at most this many grid points.
_ENVELOPE_DECAYS = 60.0
_MAX_POINTS = 200_000
# Grid points per unit of the fastest excited mode's rate: 16 per radian, ~100 per period.
_POINTS_PER_RATE = 16.0
_CHUNK = 256  # grid points propagated at once
# Eigenvector bases up to this condition number are used (errors ~ cond x 1e-16); beyond it
# (a nearly defective drift, e.g. critical damping) matrix exponentials.
_MODAL_COND = 1e4
# Speed bracket of `critical_speed`: factors 2**40 up and down from the model's own speed.
_SPEED_DOUBLINGS = 40
_SPEED_RTOL = 1e-10

# key -> (method, order, normalized) of `CrossingEstimator.first_passage`
ANALYTIC_METHODS: dict[str, tuple[str, int, bool]] = {
    "Fn1": ("truncation", 1, False),
    "Fn1_norm": ("truncation", 1, True),
    "Fg1": ("decoupling", 1, False),
    "Fn2": ("truncation", 2, False),
    "Fn2_norm": ("truncation", 2, True),
    "Fg2": ("decoupling", 2, False),
}
MONTE_CARLO_METHODS = ("mc_exact", "mc_euler")

NEGATIVE_DENSITY = "negative density"
NOT_NORMALISED = "not normalised"
NEVER_NORMALISES = "never normalises"
NEGATIVE_ESCAPE_RATE = "negative escape rate"
CLOSURE = "closure, not exact"
NO_CONVERGENCE = "does not converge in dt (white noise in the crossing variable)"
NO_DENSITY = "no density without noise (the slip is deterministic)"


# -- the noise-free slip ---------------------------------------------------------------------
class _MeanPath:
    r"""The mean path $\dot\mu = A\mu + b$, $\mu(0) = m_0$, of a linear-Gaussian slip, and
    its crossing variable $y(t) = c^\top\mu(t) - L$ relative to the stick level $L$."""

    def __init__(self, owner: str, model: FrictionModel):
        if not isinstance(model, FrictionModel):
            raise ParameterError(owner, "model", "must be a stickslip.FrictionModel", model)
        lg = model.linear_gaussian()
        if lg is None:
            raise ParameterError(
                owner, "model", f"{type(model).__name__} has no linear-Gaussian description"
            )
        A = np.asarray(lg.A, float)
        d = A.shape[0]
        # Augmented state (mu, 1): the affine drift becomes linear.
        self.M = np.zeros((d + 1, d + 1))
        self.M[:d, :d], self.M[:d, d] = A, np.asarray(lg.b, float)
        self.z0 = np.append(np.asarray(lg.m0, float), 1.0)
        self.c = np.append(np.asarray(lg.crossing, float), 0.0)
        self.level = float(np.asarray(model.stick_level))
        self.rate0 = float(self.c @ self.M @ self.z0)  # dy/dt at onset
        self.A, self.noise = A, float(np.sum((np.asarray(lg.crossing) @ np.asarray(lg.B)) ** 2))
        self.step, self.horizon = self._scales()
        # Eigenvectors of M for cheap exact evaluation between grid points; expm where M is
        # (nearly) defective, e.g. a critically damped oscillator.
        lam, V = np.linalg.eig(self.M)
        modal = np.linalg.cond(V) < _MODAL_COND
        self._modal = (lam, self.c @ V, np.linalg.inv(V)) if modal else None

    def _scales(self):
        """Grid step and horizon from the modes the path excites (a fast mode that the mean
        never enters, e.g. the friction noise's own relaxation, sets nothing). The horizon
        ends where the slowest mode has decayed by e^-60, or sooner where the envelope
        sum_j |a_j| e^(Re lambda_j t) of y(t) - y(inf) can no longer bridge the gap between
        the equilibrium and the level (when the equilibrium is below the level)."""
        lam, V = np.linalg.eig(self.A)
        b = self.M[:-1, -1]
        excited = np.ones(lam.size, bool)
        bound = math.inf
        if np.linalg.cond(V) < _MODAL_COND:  # diagonalisable: weight a_j of each mode in y(t)
            shift = np.linalg.lstsq(self.A, -b, rcond=None)[0]
            coef = np.linalg.solve(V, self.z0[:-1] - shift) * (self.c[:-1] @ V)
            excited = np.abs(coef) > 1e-12 * max(np.abs(coef).max(initial=0.0), 1e-300)
            if not excited.any():
                excited[:] = True
            decay = -float(lam.real[excited].max())
            gap = self.level - float(self.c[:-1] @ shift)
            if decay > 0 and gap > 0 and np.allclose(self.A @ shift, -b):
                total = float(np.abs(coef[excited]).sum())
                bound = max(math.log(total / gap), 0.0) / decay
        lam = lam[excited]
        fastest = max(float(np.abs(lam).max()), 1e-12)
        step = 1.0 / (_POINTS_PER_RATE * fastest)
        slowest = float(np.abs(lam.real).min())
        horizon = _ENVELOPE_DECAYS / slowest if slowest > 0 else math.inf
        horizon = min(horizon, bound + 4 * step)
        return step, min(horizon, _MAX_POINTS * step)

    def first_return(self) -> float:
        """First t > 0 with y(t) >= 0 after the path left the level; 0 if it does not leave
        it (a rising onset: an immediate re-stick); inf if it never comes back."""
        scale = max(1.0, abs(self.level), abs(float(self.c @ self.z0)))
        y0 = float(self.c @ self.z0) - self.level
        if y0 > 1e-12 * scale or (y0 >= -1e-12 * scale and self.rate0 >= 0):
            return 0.0
        h = self.step
        if self._modal is not None:
            lam, _, Vinv = self._modal
            Phi = np.real(np.linalg.inv(Vinv) @ (np.exp(lam * h)[:, None] * Vinv))
        else:
            Phi = linalg.expm(self.M * h)
        powers = [np.eye(Phi.shape[0])]
        for _ in range(_CHUNK):
            powers.append(Phi @ powers[-1])
        self._powers = np.array(powers)
        # The state at every chunk start, then y on the whole grid at once.
        n_chunks = max(1, math.ceil(self.horizon / (_CHUNK * h)))
        Z = np.empty((n_chunks + 1, self.z0.size))
        Z[0] = self.z0
        for j in range(n_chunks):
            Z[j + 1] = self._powers[_CHUNK] @ Z[j]
        self._starts = Z
        rows = np.einsum("i,kij->kj", self.c, self._powers[:_CHUNK])
        ys = np.append((Z[:-1] @ rows.T).ravel(), self.c @ Z[-1]) - self.level
        ys[0] = min(ys[0], 0.0)  # the onset sits on the level (or below it)
        return self._first_event(ys, h)

    def _local(self, k):
        """y(t) near grid point k, propagated from that point (a short, cheap exponential)."""
        t_k = k * self.step
        z_k = self._powers[k % _CHUNK] @ self._starts[k // _CHUNK]
        if self._modal is not None:
            lam, cV, Vinv = self._modal
            weights = cV * (Vinv @ z_k)
            return lambda t: float(np.real(weights @ np.exp(lam * (t - t_k)))) - self.level
        return lambda t: float(self.c @ linalg.expm(self.M * (t - t_k)) @ z_k) - self.level

    def _first_event(self, ys, h):
        """The first return on the grid values `ys` (at k h): a grid point at or above the
        level, or a peak between grid points that reaches it."""
        up = np.nonzero(ys[1:] >= 0)[0]
        k_up = up[0] + 1 if up.size else ys.size
        inner = ys[1:-1]
        curvature = np.abs(ys[2:] - 2 * inner + ys[:-2])
        # The grid misses a peak's true height by at most |y''| h^2 / 8 <~ the 2nd difference.
        peaks = np.nonzero((inner >= ys[:-2]) & (inner >= ys[2:]) & (inner > -curvature))[0] + 1
        for k in peaks[peaks < k_up]:
            y = self._local(k)
            lo, hi = (k - 1) * h, (k + 1) * h
            res = optimize.minimize_scalar(
                lambda t, y=y: -y(t), bounds=(lo, hi), method="bounded", options={"xatol": 1e-12}
            )
            if -res.fun >= 0:
                return _root(y, lo, float(res.x))
        if k_up < ys.size:
            return _root(self._local(k_up), (k_up - 1) * h, k_up * h)
        return math.inf


def _root(y, lo, hi):
    if y(hi) == 0.0:
        return hi
    return float(optimize.brentq(y, lo, hi, xtol=1e-14, rtol=4 * np.finfo(float).eps))


def deterministic_slip(model: FrictionModel) -> float:
    r"""Slip time of the noise-free slip.

    The slip follows the mean path $\mu(t)$ of the model's `linear_gaussian()` description,
    $\dot\mu = A\mu + b$ from $\mu(0) = m_0$: the noise is additive and zero-mean, so this is
    the $D = 0$ solution. The slip ends at the first $t > 0$ at which the crossing variable
    $c^\top\mu(t)$ comes back up to the stick level after leaving it.

    Found on a grid of about 100 points per period of the fastest mode the path excites,
    with a check of every grid peak that comes within the grid's resolution of the level
    (a bounded maximisation), and refined by Brent's method to machine precision. The path is
    followed until the envelope of its modes can no longer reach the level from an
    equilibrium below it, or else until its slowest mode has decayed by $e^{-60}$ (at most
    200 000 grid points).

    **Arguments:**

    - `model`: a `FrictionModel` with a linear-Gaussian description.

    **Returns:** the slip time; `0.0` if the crossing variable does not leave the level
    (rising or above it at onset: an immediate re-stick); `math.inf` if it never comes back
    (steady sliding).
    """
    return _MeanPath("deterministic_slip", model).first_return()


def _with(model, parameter, value):
    import equinox as eqx

    return eqx.tree_at(lambda m: getattr(m, parameter), model, float(value))


def critical_speed(model: FrictionModel, parameter: str = "v_b") -> float:
    r"""The highest driving speed at which the noise-free slip still comes back to the stick
    level: above it stick-slip gives way to steady sliding.

    Bisection on the model field `parameter` (the driving speed, which is also the stick
    level for the Langevin family), with every other field fixed, to a relative accuracy of
    1e-10, after a bracket by doubling or halving from the model's own value (at most 40
    times). It assumes one threshold: stick-slip at small speeds and sliding beyond. That
    holds for the Langevin family: with $x_0$ fixed, $v(t) = x_0 g(t) + v_b h(t)$ with $g$,
    $h$ the responses to the initial conditions $(1, 0)$ and $(0, 1)$, and the slip returns
    when $x_0 g(t) \ge v_b (1 - h(t))$ for some $t > 0$, which only gets harder as $v_b$
    grows ($h < 1$ for $t > 0$: the energy of the damped oscillator decays). For the
    damped oscillator ($\gamma = \zeta/2$, $\omega_d = \sqrt{\omega_0^2 - \gamma^2}$) it
    has the closed form
    $v_c = \omega_0^2 x_0 / (\omega_d \tan\varphi_c - \gamma)$ with $\varphi_c$ the root in
    $(0, \pi/2)$ of $\cos\varphi = \cos\psi\, e^{-(\gamma/\omega_d)(2\pi - \varphi - \psi)}$,
    $\tan\psi = \gamma/\omega_d$ (the first velocity maximum after onset just touches $v_b$);
    $v_c \approx \omega_0 x_0 \sqrt{\omega_d / 4\pi\gamma}$ grows without bound as
    $\zeta \to 0$.

    **Arguments:**

    - `model`: a `FrictionModel` with a linear-Gaussian description.
    - `parameter`: the name of the driving-speed field (default `"v_b"`).

    **Returns:** the critical speed; `math.inf` if the slip still returns at $2^{40}$ times
    the model's speed; `0.0` if it does not return even at $2^{-40}$ times it (e.g. an
    overdamped oscillator, which never sticks again).
    """
    owner = "critical_speed"
    _MeanPath(owner, model)  # checks the model
    if not isinstance(parameter, str) or parameter not in model.params():
        reason = f"is not a field of {type(model).__name__}"
        raise ParameterError(owner, "parameter", reason, parameter)
    start = check_positive(owner, parameter, getattr(model, parameter))

    def returns(value):
        return _MeanPath(owner, _with(model, parameter, value)).first_return() < math.inf

    if returns(start):
        lo, hi = start, 2.0 * start
        for _ in range(_SPEED_DOUBLINGS):
            if not returns(hi):
                break
            lo, hi = hi, 2.0 * hi
        else:
            return math.inf
    else:
        lo, hi = 0.5 * start, start
        for _ in range(_SPEED_DOUBLINGS):
            if returns(lo):
                break
            lo, hi = 0.5 * lo, lo
        else:
            return 0.0
    while hi - lo > _SPEED_RTOL * hi:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if returns(mid) else (lo, mid)
    return lo


# -- the report --------------------------------------------------------------------------------
@dataclasses.dataclass(frozen=True, eq=False)
class StabilityReport:
    """Validity of every method at one parameter point (from `stability_report`).

    - `failures`: method key -> the reasons it fails here (empty: no failure found); keys
      `"Fn1"`, `"Fn1_norm"`, `"Fg1"`, `"Fn2"`, `"Fn2_norm"`, `"Fg2"` (`ANALYTIC_METHODS`)
      and `"mc_exact"`, `"mc_euler"` (Monte Carlo with exact or Euler-Maruyama stepping).
    - `diagnostics`: method key -> the estimator's `diagnostics()` (mass, min_density,
      escape_rate_min, t_n) and the density's peak.
    - `regime`: `"stick-slip"`, `"multiperiodic"` or `"sliding"`.
    - `critical_speed`, `deterministic_slip_time`: see the functions of those names.
    - `p_miss`, `p_miss_se`: probability that a slip misses its first stick opportunity,
      and its binomial standard error (nan where it is not estimated).
    - `window_mass`, `window_mass_se`: probability that the slip ends in $(0, t_{max}]$,
      which each approximation's mass is checked against.
    """

    model: str
    t_max: float
    exact: bool
    critical_speed: float
    deterministic_slip_time: float
    regime: str
    p_miss: float
    p_miss_se: float
    window_mass: float
    window_mass_se: float
    immediate_probability: float
    failures: MappingProxyType
    diagnostics: MappingProxyType

    def ok(self, key: str) -> bool:
        """True when no failure of the method `key` was found."""
        if key not in self.failures:
            options = ", ".join(repr(k) for k in self.failures)
            raise ParameterError("StabilityReport.ok", "key", f"must be one of {options}", key)
        return not self.failures[key]

    def __str__(self) -> str:
        speed = f"v_c = {self.critical_speed:.6g}"
        lines = [
            f"StabilityReport: {self.model}, t in [0, {self.t_max:.4g}]",
            f"  regime: {self.regime} ({speed}; noise-free slip time "
            f"{self.deterministic_slip_time:.6g})",
        ]
        if not math.isnan(self.p_miss):
            lines.append(
                f"  P(miss first stick) = {self.p_miss:.4f} +- {self.p_miss_se:.4f}"
                f" (multiperiodic above {MULTIPERIODIC_P_MISS})"
            )
        lines.append(
            f"  mass of the slips ending in (0, t_max]: {self.window_mass:.4f}"
            + (f" +- {self.window_mass_se:.4f}" if self.window_mass_se > 0 else "")
        )
        width = max(len(k) for k in self.failures)
        for key, reasons in self.failures.items():
            extra = ""
            if key in self.diagnostics:
                extra = f"  [mass {self.diagnostics[key]['mass']:.4g}]"
            lines.append(f"  {key:{width}s}  {'; '.join(reasons) or 'ok'}{extra}")
        return "\n".join(lines)


def _describe(model):
    params = ", ".join(f"{k}={v!r}" for k, v in model.params().items())
    return f"{type(model).__name__}({params})"


def _damped_frequency(A):
    return float(np.abs(np.linalg.eigvals(A).imag).max())


def stability_report(
    model: FrictionModel,
    *,
    t_max: float | None = None,
    n_paths: int = 4000,
    seed: int = 0,
    methods: tuple[str, ...] = tuple(ANALYTIC_METHODS),
) -> StabilityReport:
    r"""Where each method fails at one parameter point of a linear-Gaussian model.

    Runs `CrossingEstimator(model, dt=dt).diagnostics()` on $[0, t_{max}]$ for each
    analytic method in `methods` (dt = 0.02, `DIAGNOSTICS_DT`, which keeps the second order
    near a second, or a fifth of the model's fastest time scale where that is shorter) and
    records the reasons each fails:

    - `"negative density"`: the density dips below -1e-3 of its peak (`NEGATIVE_TOL`);
    - `"not normalised"` (methods not normalised by construction): its mass on
      $[0, t_{max}]$ is off the probability that the slip ends in $(0, t_{max}]$ by more
      than 0.05 (`MASS_TOL`) plus 4 standard errors of that probability. The probability
      is measured by the Monte Carlo below; it is $1 - p_0$ where that does not exist (white
      noise). For `Fn1` this is the expected overcount of later upcrossings;
    - `"never normalises"`: a normalised truncation whose mass never reaches 1;
    - `"negative escape rate"` (decoupling): $\dot S(t) < 0$ somewhere (below -1e-3 of the
      peak of $n_1$);
    - white noise entering the crossing variable (`model.crossing_is_smooth` False, noise
      > 0): `"closure, not exact"` for every analytic method, and `"does not converge in dt
      (white noise in the crossing variable)"` for the Monte Carlo keys `"mc_exact"` and
      `"mc_euler"`: a path started on the level re-crosses it at once, so grid-monitored
      slip times shrink without limit as dt does, and the Brownian-bridge test makes every
      slip immediate;
    - without noise: `"no density without noise (the slip is deterministic)"`.

    The regime is `"sliding"` when the noise-free slip never returns (the driving speed is
    above `critical_speed`), `"multiperiodic"` when the probability
    $p_{miss} = P(T_{sl} > T_{det} + \pi/\omega_d)$ that a slip misses its first stick
    opportunity exceeds 0.05 (`MULTIPERIODIC_P_MISS`; $T_{det}$ the noise-free slip time,
    $\omega_d$ the damped frequency of $A$), and `"stick-slip"` otherwise. $p_{miss}$ and
    the window mass come from `simulate(model, n_paths, dt=0.01, solver="exact")` (well
    posed noise only: $p_{miss}$ is nan for white noise, where the Monte Carlo has no
    dt -> 0 limit other than the immediate re-stick, so that the regime is then stick-slip
    or sliding; and nan in the sliding regime).

    `ApproximationWarning`s are suppressed: the report is the record. A report costs one to
    two seconds on a 2-core CPU once the estimator's kernels are compiled (the first call
    per state size and grid compiles them: several seconds more).

    **Arguments:**

    - `model`: a `FrictionModel` with a linear-Gaussian description.
    - `t_max`: end of the window; default 2 periods $2\pi/\omega_d$ of the damped mean path
      (it holds the first stick opportunity, $T_{det} < 2\pi/\omega_d$, and the next one;
      it depends on $A$ alone, so reports over driving speeds and noise levels share one
      compiled grid), or 3 times the slowest relaxation time if the path does not oscillate.
    - `n_paths`, `seed`: of the Monte Carlo.
    - `methods`: the analytic method keys to check (`ANALYTIC_METHODS`).

    **Returns:** a `StabilityReport`.
    """
    if isinstance(model, CreepingSlider):
        # Friction with memory: the linear stability of steady sliding, its limit cycle.
        from ._sliding import sliding_regime

        return sliding_regime(model)
    owner = "stability_report"
    path = _MeanPath(owner, model)
    n_paths = check_int(owner, "n_paths", n_paths, minimum=2)
    seed = check_int(owner, "seed", seed, minimum=0)
    methods = tuple(methods) if not isinstance(methods, str) else (methods,)
    for key in methods:
        if key not in ANALYTIC_METHODS:
            options = ", ".join(repr(k) for k in ANALYTIC_METHODS)
            raise ParameterError(owner, "methods", f"must be among {options}", key)
    omega_d = _damped_frequency(path.A)
    if t_max is None:
        if omega_d > 0:
            t_max = 2 * 2 * math.pi / omega_d
        else:
            slowest = float(np.abs(np.linalg.eigvals(path.A).real).min())
            t_max = 3.0 / slowest if slowest > 0 else 3 * path.horizon
    t_max = check_positive(owner, "t_max", t_max)
    t_det = path.first_return()
    fast, slow = time_scales(model)
    v_c = critical_speed(model) if "v_b" in model.params() else math.nan
    white = not model.crossing_is_smooth and path.noise > 0
    noiseless = _noise_free(model)

    failures: dict[str, list[str]] = {k: [] for k in (*methods, *MONTE_CARLO_METHODS)}
    diagnostics: dict[str, dict[str, Any]] = {}

    # Monte Carlo: p_miss and the mass of the slips ending in (0, t_max].
    window, window_se, p_miss, p_miss_se = _monte_carlo(
        model, n_paths, seed, t_max, t_det, omega_d, slow, noiseless, white
    )
    p0, window = _check_methods(model, methods, t_max, fast, white, noiseless, window,
                                window_se, failures, diagnostics)  # fmt: skip
    if white:
        for key in MONTE_CARLO_METHODS:
            failures[key].append(NO_CONVERGENCE)

    if math.isinf(t_det):
        regime = "sliding"
    elif p_miss > MULTIPERIODIC_P_MISS:
        regime = "multiperiodic"
    else:
        regime = "stick-slip"
    return StabilityReport(
        model=_describe(model),
        t_max=float(t_max),
        exact=bool(model.crossing_is_smooth),
        critical_speed=float(v_c),
        deterministic_slip_time=float(t_det),
        regime=regime,
        p_miss=p_miss,
        p_miss_se=p_miss_se,
        window_mass=float(window),
        window_mass_se=window_se,
        immediate_probability=float(p0),
        failures=MappingProxyType({k: tuple(v) for k, v in failures.items()}),
        diagnostics=MappingProxyType(diagnostics),
    )


def _monte_carlo(model, n_paths, seed, t_max, t_det, omega_d, slow, noiseless, white):
    """The Monte Carlo's mass of the slips ending in (0, t_max] (nan for white noise, whose
    slips end at once) and the probability that a path misses the first stick opportunity,
    each with its standard error."""
    p_miss = p_miss_se = math.nan
    if noiseless:
        window, window_se = (1.0 if 0 < t_det <= t_max else 0.0), 0.0
        if math.isfinite(t_det) and omega_d > 0:
            p_miss, p_miss_se = 0.0, 0.0
    elif white:
        window, window_se = math.nan, 0.0
    else:
        from ._simulate import simulate

        miss_at = t_det + math.pi / omega_d if (math.isfinite(t_det) and omega_d > 0) else None
        dt_mc = MONTE_CARLO_STEP * slow
        horizon = max(t_max, miss_at or 0.0) + dt_mc
        ens = simulate(model, n_paths, dt_mc, horizon, seed, solver="exact")
        T = np.where(ens.stuck, ens.slip_time, np.inf)
        q = float(np.mean((T > 0) & (T <= t_max) & ~ens.immediate))
        window, window_se = q, math.sqrt(q * (1 - q) / n_paths)
        if miss_at is not None:
            p_miss = float(np.mean(T > miss_at))
            p_miss_se = math.sqrt(p_miss * (1 - p_miss) / n_paths)
    return window, window_se, p_miss, p_miss_se


def _check_methods(model, methods, t_max, fast, white, noiseless, window, window_se,
                   failures, diagnostics):  # fmt: skip
    """Each analytic method's first-passage density on the window, checked (negative, not
    normalised, ...): its reasons appended to `failures[key]`, its numbers to
    `diagnostics[key]`. Returns the probability of an immediate stick and the window's mass
    (the estimator's, `1 - p0`, for white noise)."""
    if methods:
        from ._estimate import CrossingEstimator
        from ._notes import collecting_notes

        with collecting_notes():  # (its notes dropped: thread-safe, unlike catch_warnings)
            dt = min(DIAGNOSTICS_DT, fast / DIAGNOSTICS_PER_SCALE)
            est = CrossingEstimator(model, dt=dt)
            p0 = est.immediate_probability
            if white:
                window = 1.0 - p0
            grid = np.arange(int(math.ceil(t_max / est.dt - 1e-9)) + 1) * est.dt
            n1_peak = float(np.max(est.n1(grid)))
            for key in methods:
                method, order, normalized = ANALYTIC_METHODS[key]
                info = est.diagnostics(t_max, method, order, normalized)
                F = est.first_passage(grid, method, order, normalized)
                info["peak"] = float(np.max(F))
                diagnostics[key] = info
                reasons = failures[key]
                if noiseless:
                    reasons.append(NO_DENSITY)
                    continue
                if info["min_density"] < -NEGATIVE_TOL * max(info["peak"], 0.0):
                    reasons.append(NEGATIVE_DENSITY)
                if normalized:
                    if info["t_n"] is None:
                        reasons.append(NEVER_NORMALISES)
                elif abs(info["mass"] - window) > MASS_TOL + Z_SAMPLING * window_se:
                    reasons.append(NOT_NORMALISED)
                if method == "decoupling" and info["escape_rate_min"] < -NEGATIVE_TOL * n1_peak:
                    reasons.append(NEGATIVE_ESCAPE_RATE)
                if white:
                    reasons.append(CLOSURE)
    else:
        p0 = math.nan
    return p0, window


def _noise_free(model) -> bool:
    lg = model.linear_gaussian()
    return not np.any(np.asarray(lg.B)) and not np.any(np.asarray(lg.P0))
