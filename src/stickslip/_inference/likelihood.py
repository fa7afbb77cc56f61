r"""The likelihood `fit` maximises: a *simulated likelihood with common random numbers*.

- At a parameter value $\theta$ the model is simulated (`simulate`, exact in law for
  linear-Gaussian slips at any step) for `n_sim` cycles with one fixed seed, through the
  data's measurement where they have one (`forward.simulate_values`).
- Each observed quantity's density is a Gaussian kernel estimate of the simulated values
  (slip times, periods and positive stick times on a log scale, `to_fit_scale`; slip
  distances on their own scale), one bandwidth per quantity fixed from the data
  (`bandwidth_of`), the same at every $\theta$; a duration's atom at zero (a stick of zero
  length) is a point mass (`_zero_fraction`).
- The data are smoothed by the same kernel as the model (`_log_density`); the columns of
  one cycle add up (a composite likelihood; rows are cycles): `cycle_log_likelihood` gives
  those per-cycle terms for a `FitResult`.
"""

from __future__ import annotations

import math

import numpy as np

from .._errors import DataError, ParameterError, check_int
from .data import KINDS as KINDS  # the columns, here too: they are the likelihood's terms
from .data import LOG_KINDS, check_data, to_fit_scale
from .forward import simulate_values
from .params import model_kwargs
from .result import FitResult

KDE_BINS = 4096  # the binned kernel estimate's grid
# A measured trace with fewer cycles than this has no density to compare (the data need 10,
# `data.MIN_CYCLES`; a kernel estimate of the model's law from a few dozen is mostly noise).
MIN_SIMULATED = 50
# The kernel estimate is not taken below the density one simulated value gives at its own
# centre, 1 / (n h sqrt(2 pi)) (times this): where fewer than about one simulated value
# falls within a bandwidth the estimate is that of a value's presence or absence, and a
# datum there scored log f jumping by ~9 units when one simulated value came or went (the
# defensive normal's 1/n mixture sets the level without one). On the measured slider
# (`examples/slider_fit.py`: three data slips shorter than one sampling interval, which the
# measured model makes only rarely) the log-likelihood jumped 5-15 units between points
# 0.5 % apart in omega0 or D, and the fit's surface was not concave; with the floor (and the
# force noise keyed by cycle), steps of 0.1-2.5 units around a clear maximum
# (`density_table`). The floor lies below the density wherever the model puts more than a
# value per bandwidth, which is where the data fall when the model holds (a datum beyond it
# is scored alike at every parameter: it no longer pulls the estimate), and it vanishes as
# n_sim grows.
FLOOR_POINTS = 1.0


def cycle_log_likelihood(
    result, params: dict | None = None, data: dict | None = None, *,
    n_sim: int | None = None, seed: int | None = None,
) -> np.ndarray:  # fmt: skip
    r"""The per-cycle terms of a fit's smoothed log-likelihood: one value per cycle (row),
    summed over the columns, as `fit` adds them up.

    **Arguments:**

    - `result`: a `FitResult` (from `fit`): its model, column bandwidths, measurement
      (none for per-cycle values; a `Cycles`' trace measurement), `dt`, `t_max`.
    - `params`: `{name: value}` for any of the model's parameters (a dict entry named with a
      dot, `"threshold_params.sd"`); the others at the fit's model (default: the estimate).
    - `data`: the cycles, a dict with the fit's columns (default: the fit's own data),
      taken through the fit's measurement.
    - `n_sim`, `seed`: the simulation (default: the fit's own, so that at the estimate and
      the fit's data the terms add up to `result.log_likelihood`).

    **Returns:** an array of the per-cycle terms $\sum_k \ell_k(\theta; y_{ik})$, one per row
    of `data` (as checked by `fit`); all `-inf` where the model's measured trace shows no
    cycles.
    """
    owner = "cycle_log_likelihood"
    if not isinstance(result, FitResult):
        raise ParameterError(owner, "result", "must be a FitResult (from fit)", type(result))
    d = result.diagnostics
    n_sim = d.n_sim if n_sim is None else check_int(owner, "n_sim", n_sim, minimum=1000)
    seed = d.seed if seed is None else check_int(owner, "seed", seed, minimum=0)
    if data is None:
        cols = result.data
    else:
        cols = check_data(data, measured=d.measurement is not None)
        if set(cols) != set(result.data):
            raise ParameterError(
                owner, "data", f"must have the fit's columns ({', '.join(result.data)})",
                sorted(cols),
            )  # fmt: skip
    Model = type(result.model)
    known = Model.parameters()
    values = dict(params or {})
    for k in values:
        head, _, entry = str(k).partition(".")
        base = result.model.params().get(head)
        if head not in known or (entry and not hasattr(base, "items")):
            raise ParameterError(
                owner, f"params['{k}']", f"is not a parameter of {Model.__name__} (parameters: "
                f"{', '.join(known)})",
            )  # fmt: skip
    kwargs = model_kwargs(result.model)
    for k, v in values.items():
        head, _, entry = str(k).partition(".")
        kwargs[head] = {**kwargs[head], entry: v} if entry else v
    try:
        model = Model(**kwargs)
    except (ValueError, ArithmeticError) as err:
        raise ParameterError(
            owner, "params", f"do not make a {Model.__name__} ({type(err).__name__}: {err})"
        ) from None
    terms = _per_cycle(model, cols, d.bandwidth, n_sim, d.dt, d.t_max, seed,
                       d.measurement)  # fmt: skip
    if terms is None:
        return np.full(next(iter(cols.values())).size, -np.inf)
    return np.sum([terms[k] for k in cols], axis=0)


def _per_cycle(model, data, bandwidth, n_sim, dt, t_max, seed, measurement) -> dict | None:
    """Each column's per-cycle terms at `model`: `_log_density` of the data against `n_sim`
    cycles simulated with `seed` through `measurement` (`None`: per-cycle values). `None`
    (a log-likelihood of -inf) where the measured trace shows no cycles, or fewer than
    `MIN_SIMULATED`: a model whose trace the measurement cannot resolve does not make the
    data."""
    return scored_samples(data, sample(model, n_sim, dt, t_max, seed, measurement), bandwidth,
                   measurement)  # fmt: skip


def sample(model, n_sim, dt, t_max, seed, measurement) -> dict | None:
    """`_per_cycle`'s simulated cycles (`None` where the measured trace shows none)."""
    try:
        return simulate_values(model, n_sim, dt, t_max, seed, measurement)
    except DataError:
        if measurement is None:
            raise
        return None


def scored_samples(data, sim, bandwidth, measurement) -> dict | None:
    """`_per_cycle`'s terms of `data` against the simulated cycles `sim` (`sample`)."""
    if sim is None:
        return None
    if measurement is not None and min(np.size(sim[k]) for k in data) < MIN_SIMULATED:
        return None
    return {k: _log_density(k, data[k], sim[k], bandwidth[k]) for k in data}


# The simulation's noise in the estimate (`intervals._jackknife`): the cycles simulated at a
# design point split into this many contiguous blocks, each left out in turn. A block of a
# measured trace's cycles is ~100 successive cycles (at n_sim 1000), far longer than the
# dependence a threshold or a state carries between cycles.
JACKKNIFE_BLOCKS = 10


def jackknife_values(data, sim, bandwidth, measurement, blocks=JACKKNIFE_BLOCKS):
    """The log-likelihood of `data` against the simulated cycles `sim` with each of
    `blocks` contiguous blocks of them left out in turn (`-inf` where too few are left,
    or `sim` is `None`): one value a block. Each block is binned once (`_binned`); a
    replicate's density is the whole's counts less the block's."""
    out = np.full(blocks, -np.inf)
    if sim is None:
        return out
    total = np.zeros(blocks)
    for k in data:
        x = np.asarray(data[k], float)
        h = bandwidth[k]
        lo, hi, mu, sd = _grid(k, x, h)
        a = np.asarray(sim[k], float)
        edges = [b * a.size // blocks for b in range(blocks + 1)]
        parts = [_binned(k, a[edges[b] : edges[b + 1]], lo, hi, KDE_BINS) for b in range(blocks)]
        whole = [sum(p[i] for p in parts) for i in range(4)]
        for b, part in enumerate(parts):
            counts, n, zeros, finite = (w - p for w, p in zip(whole, part, strict=True))
            if measurement is not None and a.size - (edges[b + 1] - edges[b]) < MIN_SIMULATED:
                total[b] = -np.inf
                continue
            table = _table(k, counts, n, zeros, finite, h, lo, hi, mu, sd, fft=True)
            total[b] += float(np.sum(log_density_at(k, x, table)))
    return total


def bandwidth_of(y, n_sim) -> float:
    iqr = np.subtract(*np.percentile(y, [75, 25])) / 1.349
    spread = min(np.std(y), iqr) if iqr > 0 else np.std(y)
    return float(0.9 * max(spread, 1e-12) * n_sim ** (-0.2))


def _zero_fraction(n_zero: int, n_finite: int) -> float:
    r"""The simulated fraction of zeros, $p_0 = (k + 1/2)/(n + 1)$ for $k$ zeros among $n$
    finite values: the Jeffreys-type half count keeps $\log p_0$ and $\log(1 - p_0)$ finite
    when no simulated value (or every one) is zero, and differs from $k/n$ by less than
    $1/n$."""
    return (n_zero + 0.5) / (n_finite + 1)


def _log_density(kind, x, sim, h):
    r"""Per-cycle contributions to the smoothed log-likelihood, one per datum. For a positive
    datum $y_i$ (on the kind's scale), $\int K_h(y - y_i) \log \hat f(y)\,dy$, where
    $\hat f = f_\theta * K_h$ is the kernel estimate of the simulated positive values.
    Smoothing the data with the same kernel as the model keeps the estimator consistent at
    a fixed bandwidth: the expected value, $\int (f_0 * K_h) \log (f_\theta * K_h)$, is
    largest at the true $\theta$ (Gibbs' inequality), where the kernel estimate evaluated
    at the raw data is biased by the smoothing (measured: D 14 % low on the public set). A
    mixture weight 1/n_sim of a broad normal keeps a datum far from every simulated value
    finite, and the estimate is floored at the density one simulated value gives at its
    centre (`FLOOR_POINTS`): a datum where the model puts less than a value per bandwidth
    scores the same whichever rare value comes or goes.

    A duration's law has an atom at 0 (a stick of zero length: 38 % of the public set's):
    a zero datum contributes $\log p_0$, a positive one $\log(1 - p_0)$ plus the density
    of the positive values, with $p_0$ the simulated fraction of zeros (`_zero_fraction`).
    Dropping the zeros instead biased D to 0.227 for a truth of 0.4 from stick times."""
    x = np.asarray(x, float)
    lo, hi, mu, sd = _grid(kind, x, h)
    table = density_table(kind, sim, h, lo, hi, KDE_BINS, mu, sd)
    return log_density_at(kind, x, table)


def _grid(kind, x, h):
    """The table's span for data `x` (their range on the kind's scale, 8 bandwidths on
    either side) and its defensive normal's centre and sd: `(lo, hi, mu, sd)`."""
    y = to_fit_scale(kind, x)
    return y.min() - 8 * h, y.max() + 8 * h, np.mean(y), 3.0 * max(np.std(y), h)


def density_table(kind, sim, h, lo, hi, bins, mu, sd):
    """The smoothed log-density of `sim` (`_log_density`) tabulated on `bins` bins over
    `[lo, hi]` (the kind's scale), its defensive normal of centre `mu` and sd `sd`, and the
    zero fraction: `(centres, smoothed log-density, p0)`, for `log_density_at`. One table
    serves any data inside `[lo + 8h, hi - 8h]` (the goodness check's replicates)."""
    return _table(kind, *_binned(kind, sim, lo, hi, bins), h, lo, hi, mu, sd)


def _binned(kind, sim, lo, hi, bins):
    """`sim`'s counts on the table's bins (the kind's scale), its finite values' number and
    its zeros' (`density_table`)."""
    finite = sim[np.isfinite(sim)]
    # The grid spans the data (fixed for every theta): simulated values past it count in n
    # but add no density there (they lie over 8 bandwidths from every datum). A grid that
    # spanned the simulated values moved with the smallest of them (a stick of 1e-6 is -14
    # on the log scale) and the binning with it: the surface jumped ~10 units between
    # parameters 1e-4 apart, and Nelder-Mead ran into its cap.
    s = to_fit_scale(kind, finite)
    # equal bins by range: numpy bins them arithmetically (given the edges it sorts the
    # sample, twice the time; the counts are the same)
    counts = np.histogram(s, bins, range=(lo, hi))[0].astype(float)
    return counts, s.size, np.count_nonzero(finite == 0), finite.size


def _table(kind, counts, n_scaled, n_zero, n_finite, h, lo, hi, mu, sd, fft=False):
    """`density_table` from `_binned`'s counts: of the `n_scaled` values on the kind's
    scale (a duration's positive ones), and of the `n_zero` zeros among `n_finite`.
    `fft`: the kernel's convolutions by FFT (the jackknife's many tables: the same
    numbers to ~1e-12, a tenth of the time for a kernel of hundreds of bins)."""
    bins = counts.size
    n = max(n_scaled, 1)
    edges = np.linspace(lo, hi, bins + 1)
    dx = edges[1] - edges[0]
    half = max(1, int(math.ceil(6 * h / dx)))
    k = np.arange(-half, half + 1) * dx
    kernel = np.exp(-0.5 * (k / h) ** 2)
    kernel /= kernel.sum()
    convolve = _fft_convolve if fft else np.convolve
    f = convolve(counts, kernel, mode="same") / (n * dx)
    centres = 0.5 * (edges[1:] + edges[:-1])
    broad = np.exp(-0.5 * ((centres - mu) / sd) ** 2) / (sd * math.sqrt(2 * math.pi))
    eps = 1.0 / n
    floor = FLOOR_POINTS / (n * h * math.sqrt(2 * math.pi))  # (see FLOOR_POINTS)
    density = np.maximum((1 - eps) * f + eps * broad, floor)
    smoothed_log = convolve(np.log(density), kernel, mode="same")
    p0 = _zero_fraction(n_zero, n_finite) if kind in LOG_KINDS else None
    return centres, smoothed_log, p0


def _fft_convolve(x, kernel, mode="same"):
    """`np.convolve(x, kernel, mode="same")` by FFT, for a kernel no longer than `x`."""
    n = x.size + kernel.size - 1
    size = 1 << (n - 1).bit_length()
    full = np.fft.irfft(np.fft.rfft(x, size) * np.fft.rfft(kernel, size), size)[:n]
    start = (kernel.size - 1) // 2
    return full[start : start + x.size]


def log_density_at(kind, x, table) -> np.ndarray:
    """Per-datum terms of `_log_density` from a `density_table`."""
    centres, smoothed_log, p0 = table
    x = np.asarray(x, float)
    out = np.empty(x.size)
    positive = x > 0 if kind in LOG_KINDS else np.ones(x.size, bool)
    y = to_fit_scale(kind, x)
    logf = np.interp(y, centres, smoothed_log)
    if kind in LOG_KINDS:
        logf = logf - y + math.log1p(-p0)  # the density of x = exp(y), given x > 0
        out[~positive] = math.log(p0)
    out[positive] = logf
    return out
