"""Where the likelihood is largest, and its curvature there.

The maximum is found by a coarse grid over the `free` box (`_design`) and Nelder-Mead from
its best point (`search`), in fit coordinates (log for positive parameters); then a
quadratic plus a cubic term per axis is fitted by least squares on a design of steps
`DESIGN_STEP` around it (`local_surface`: the cubic terms keep the surface's skew out of
the vertex): the vertex is the estimate. The information the intervals use is the plain
quadratic's curvature through both seeds' values (`quadratic_hessian`,
`intervals.with_plain_bread`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .._errors import ParameterError

DESIGN_STEP = 0.1  # the quadratic design's step (log coordinates for positive parameters)
GRID_POINTS = 5  # per free parameter, for the coarse start (p <= 2; 8 p points above)
# Nelder-Mead's cap a free parameter: converged on the simplex's size it took 22 evaluations
# for one parameter and 35 for two (measured, slip and stick times); the cap is 4-5 x that.
MAXFEV_PER_PARAMETER = 100
# A design step is narrowed, axis by axis, until the log-likelihood falls by at most this
# much over one step from the centre: the polynomial is a local model. On the measured
# slider's random threshold (4 free, steps of 0.3) one step along omega0 fell by 160-280
# units and two by 390-840, and the cubic's misfit there (tens of units) swamped the few
# units D moves: the fitted curvature along D came out positive (+174) and the fit had no
# intervals. Twenty units stay far above the simulation's noise at a point (a few units
# through a measurement, where the design step is wide for that reason).
MAX_STEP_DROP = 20.0
# Nelder-Mead from several of the coarse grid's best points when three or more parameters
# are free: the 8 p points of a Sobol grid in four dimensions are sparse, and a random
# threshold's mean and sd trade along a ridge (a low mean with a wide spread truncated at
# 0 against the truth): from the single best grid point Nelder-Mead ended on that ridge in
# 3 of 4 independent traces (mean 0.34-0.50, sd 0.96-1.04 for a truth of 1 and 0.63),
# 22 log-likelihood units below the truth's own value. The best of the runs is kept.
STARTS, START_APART = 3, 0.25


def search(loglik, lo, hi, free) -> tuple[np.ndarray, dict, list[str]]:
    """The coarse grid over the box, then Nelder-Mead from its best point. Returns the best
    point (fit coordinates, inside the box), the optimiser's record and its warnings."""
    start = _design(lo, hi)
    values = [loglik(u)[0] for u in start]
    if not np.any(np.isfinite(values)):
        raise ParameterError(
            "fit",
            "free",
            f"the model could not be built at any of the {len(start)} starting points of the box",
            free,
        )
    from scipy.optimize import minimize

    cap = _max_evaluations(lo.size)
    runs = []
    for best in _starts(start, values, lo, hi):
        simplex = np.vstack([best, best + 0.15 * np.diag(hi - lo)])
        runs.append(minimize(
            lambda u: -loglik(u)[0], best, method="Nelder-Mead",
            options=dict(xatol=0.02, fatol=np.inf, maxfev=cap, initial_simplex=simplex),
        ))  # fmt: skip
    res = min(runs, key=lambda r: r.fun if np.isfinite(r.fun) else np.inf)
    # Converged on the simplex's size alone (fatol infinite): the simulator's draws move
    # with the parameters (a change of 1e-12 in D moved every simulated slip time, by 1e-3
    # typically), so points 1e-4 apart differ by several log-likelihood units and a value
    # tolerance (0.2 before) was never met: Nelder-Mead ran into its cap. The polynomial
    # below, on steps of 0.1, finds the maximum more precisely than 0.02 anyway.
    said = []
    if res.status == 1:  # scipy: the cap on evaluations (2 is the cap on iterations)
        said.append(
            f"Nelder-Mead stopped on its cap of {cap} evaluations "
            "before converging: the estimate is the polynomial vertex around its last best "
            "point; check it with a narrower box"
        )
    record = dict(success=bool(res.success), message=str(res.message),
                  evaluations=int(sum(r.nfev for r in runs)), cap=cap, starts=len(runs),
                  best_start=int(runs.index(res)))  # fmt: skip
    return np.clip(res.x, lo, hi), record, said


def _starts(points, values, lo, hi) -> list[np.ndarray]:
    """Where Nelder-Mead starts: the grid's best point, and from three free parameters on
    up to `STARTS` - 1 more of the best, each at least `START_APART` of the box from those
    taken (in some parameter)."""
    order = [j for j in np.argsort(values)[::-1] if np.isfinite(values[j])]
    chosen = [points[order[0]]]
    if lo.size < 3:
        return chosen
    width = np.where(hi > lo, hi - lo, 1.0)
    for j in order[1:]:
        if len(chosen) == STARTS:
            break
        if all(np.max(np.abs(points[j] - c) / width) > START_APART for c in chosen):
            chosen.append(points[j])
    return chosen


@dataclasses.dataclass(frozen=True)
class _Surface:
    """The polynomial fitted to the log-likelihood around `centre` (fit coordinates):
    the `nominal` design and the points evaluated (`design`: clipped at the box), their
    `values` and per-cycle `scores`, the vertex's `shift` from the centre (`None`: no
    vertex near it), the `hessian` there, and the axes `clipped` at the box."""

    centre: np.ndarray
    steps: np.ndarray
    nominal: np.ndarray
    design: np.ndarray
    values: list
    scores: list
    shift: np.ndarray | None
    hessian: np.ndarray
    clipped: list

    @property
    def warnings(self) -> list[str]:
        said = []
        if self.clipped:
            said.append(
                f"the surface design around the estimate reaches past the box in "
                f"{', '.join(self.clipped)}: those points were evaluated and regressed at the "
                "box's edge (a one-sided fit there): widen the box"
            )
        if self.shift is None:
            said.append(
                "the polynomial fitted to the surface has no maximum within 2 design steps of "
                "the best point found (the surface is rough or flat there): the estimate is "
                "that point, and the curvature the quadratic's"
            )
        return said

    def vertex(self, lo, hi) -> np.ndarray:
        """The estimate: the vertex (inside the box), or the centre if there is none."""
        return self.centre if self.shift is None else np.clip(self.centre + self.shift, lo, hi)


def local_surface(loglik, u_hat, lo, hi, data, names, step=DESIGN_STEP) -> _Surface:
    """The maximum and the observed information from a polynomial fitted to the surface
    around `u_hat`: quadratic, plus a cubic term along each axis, on steps of DESIGN_STEP
    (wide against the surface's Monte Carlo roughness; on steps of one standard error it
    drowned the curvature, and what it leaves is measured by the second seed, see
    `intervals.mc_noise_report`), each narrowed where one step falls by more than
    `MAX_STEP_DROP` (`_narrowed`). The cubic terms take the surface's skew out of the vertex: a
    quadratic alone put it 3-4 % low. Points past the box are evaluated at the box (`loglik`
    clips) and so regressed where they were evaluated."""
    design_steps = np.full(len(names), step)
    known: dict[bytes, tuple] = {}  # the points evaluated, by their coordinates

    def evaluated(u):
        key = np.asarray(u, float).tobytes()
        if key not in known:
            known[key] = loglik(u)
        return known[key]

    for attempt in range(2):
        design_steps = _narrowed(evaluated, u_hat, design_steps, lo, hi)
        nominal = quadratic_design(u_hat, design_steps)
        design = np.clip(nominal, lo, hi)
        values, scores = evaluate(design, evaluated, data)
        shift, H = polynomial_vertex(design - u_hat, np.array(values), design_steps)
        best_point = int(np.argmax(values))
        if shift is not None or attempt == 1 or best_point == 0:
            break
        # no vertex near Nelder-Mead's point (a rough surface can leave it off the
        # maximum): once more around the design's best point
        u_hat = design[best_point]
    clipped = [k for i, k in enumerate(names) if np.any(design[:, i] != nominal[:, i])]
    return _Surface(
        centre=u_hat, steps=design_steps, nominal=nominal, design=design, values=values,
        scores=scores, shift=shift, hessian=H, clipped=clipped,
    )  # fmt: skip


def _narrowed(loglik, u, steps, lo, hi) -> np.ndarray:
    """The design steps, each axis's narrowed (never widened) so that the log-likelihood
    falls by at most `MAX_STEP_DROP` over one step from `u`: the mean fall at +-1 step
    along the axis (the design's own points, evaluated first), scaled as a quadratic's
    (a step times sqrt(MAX_STEP_DROP / fall)); an axis clipped at the box on either side,
    or with a point the model refuses, keeps its step."""
    steps = np.array(steps, float)
    centre = loglik(u)[0]
    if not np.isfinite(centre):
        return steps
    for i in range(u.size):
        falls = []
        for sign in (-1.0, 1.0):
            v = u.copy()
            v[i] += sign * steps[i]
            if not lo[i] <= v[i] <= hi[i]:
                break
            falls.append(centre - loglik(v)[0])
        if len(falls) == 2 and np.all(np.isfinite(falls)):
            fall = float(np.mean(falls))
            if fall > MAX_STEP_DROP:
                steps[i] *= np.sqrt(MAX_STEP_DROP / fall)
    return steps


def _design(lo, hi):
    p = lo.size
    if p <= 2:
        axes = [np.linspace(a, b, GRID_POINTS + 2)[1:-1] for a, b in zip(lo, hi, strict=True)]
        return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, p)
    import warnings

    from scipy.stats import qmc

    with warnings.catch_warnings():
        # (scipy says a Sobol' sample's balance needs 2^m points: a coarse grid that only
        # spreads its points over the box does not; the user saw the warning at every fit
        # of three free parameters)
        warnings.simplefilter("ignore", UserWarning)
        return qmc.scale(qmc.Sobol(p, seed=0).random(8 * p), lo, hi)


def quadratic_design(u, steps):
    """The centre, 4 points along each axis (+-1, +-2 steps) and 4 diagonal points per pair."""
    p = u.size
    pts = [u]
    for i in range(p):
        for m in (-2, -1, 1, 2):
            e = np.zeros(p)
            e[i] = m * steps[i]
            pts.append(u + e)
        for j in range(i + 1, p):
            for a, b in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
                e = np.zeros(p)
                e[i], e[j] = a * steps[i], b * steps[j]
                pts.append(u + e)
    return np.array(pts)


def polynomial_vertex(du, values, steps):
    """Fit c + g.du + du.Q.du / 2 + sum_i k_i du_i^3 by least squares; return the vertex
    nearest the centre (Newton from 0, `None` if it leaves two steps) and the Hessian there
    (the quadratic's alone if there is no vertex)."""
    p = du.shape[1]
    ok = np.isfinite(values)
    pairs = _pairs(p)
    coef = np.linalg.lstsq(polynomial_terms(du)[ok], values[ok], rcond=None)[0]
    g = coef[1 : 1 + p]
    Q = _curvature(p, coef)
    k = coef[1 + p + len(pairs) :]
    x = np.zeros(p)
    for _ in range(20):
        grad = g + Q @ x + 3 * k * x**2
        hess = Q + np.diag(6 * k * x)
        try:
            step = np.linalg.solve(hess, -grad)
        except np.linalg.LinAlgError:
            return None, Q
        x = x + step
        if np.any(np.abs(x) > 2 * steps):
            return None, Q
        if np.all(np.abs(step) < 1e-6 * steps):
            break
    return x, Q + np.diag(6 * k * x)


def quadratic_hessian(du, values) -> np.ndarray | None:
    """The Hessian of the plain quadratic (no cubic terms) fitted by least squares to
    `values` at offsets `du` from the design's centre; `None` where the finite points do
    not determine it (too few, or a pair's diagonal points lost: its cross term would be
    read as zero)."""
    p = du.shape[1]
    ok = np.isfinite(values)
    X = polynomial_terms(du)[:, : 1 + p + len(_pairs(p))]
    coef, _, rank, _ = np.linalg.lstsq(X[ok], np.asarray(values, float)[ok], rcond=None)
    if rank < X.shape[1]:
        return None
    return _curvature(p, coef)


def _curvature(p: int, coef) -> np.ndarray:
    """The symmetric curvature matrix from a fit's coefficients in `polynomial_terms`'
    order (the constant, p slopes, then the curvature's `_pairs`)."""
    Q = np.zeros((p, p))
    for (i, j), v in zip(_pairs(p), coef[1 + p :], strict=False):
        Q[i, j] = Q[j, i] = v
    return Q


def _pairs(p: int) -> list[tuple[int, int]]:
    """The curvature's index pairs (i <= j), in `polynomial_terms`' column order."""
    return [(i, j) for i in range(p) for j in range(i, p)]


def polynomial_terms(du: np.ndarray) -> np.ndarray:
    """The columns of the surface's polynomial at offsets `du` (points x p): 1, du_i, the
    curvature's du_i du_j (halved on the diagonal, `_pairs`' order) and du_i^3; shared by
    `polynomial_vertex` and `compare._polynomial_max`."""
    p = du.shape[1]
    cols = [np.ones(len(du))] + [du[:, i] for i in range(p)]
    cols += [du[:, i] * du[:, j] * (0.5 if i == j else 1.0) for i, j in _pairs(p)]
    cols += [du[:, i] ** 3 for i in range(p)]
    return np.stack(cols, axis=1)


def evaluate(design, loglik, data):
    """The log-likelihood at each design point and its per-cycle terms summed over the
    columns (a cycle's score: the columns of one cycle are dependent)."""
    values, scores = [], []
    for u in design:
        v, terms = loglik(u)
        values.append(v)
        scores.append(None if terms is None else np.sum([terms[k] for k in data], axis=0))
    return values, scores


def _max_evaluations(p: int) -> int:
    """Nelder-Mead's cap: MAXFEV_PER_PARAMETER a free parameter (30 a parameter, with a
    value tolerance the rough surface never met, was hit in most two-parameter fits)."""
    return MAXFEV_PER_PARAMETER * p
