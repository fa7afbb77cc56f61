"""Inference: model parameters from measured cycles, and whether the model fits them.

One concept a module (the public names are re-exported from `stickslip`):

- `data`: the columns given and their checks (what cannot be fitted is refused with the
  evidence); a `Cycles`' measurement read from it;
- `params`: the model class, `fixed` and `free` (dotted names for dict entries), the box,
  the fit coordinates, the memory an evaluation needs;
- `forward`: the simulated cycles as the data see them (per cycle, or through the
  measurement), `dt`, `t_max`;
- `measurement`: the measurement inside the forward model (a sampled, noisy trace);
- `likelihood`: the smoothed kernel log-likelihood, zero durations as a point mass;
  `cycle_log_likelihood`;
- `surface`: the search for the maximum and the polynomial fitted around it;
- `intervals`: the sandwich covariance, the Monte Carlo noise check, the Wald intervals;
- `estimator`: the estimator, a short composition of the modules above;
- `result`: `FitResult`;
- `goodness`: `goodness_of_fit`, `GoodnessOfFit`;
- `compare`: `compare_fits`, `Comparison` (model choice);
- `fit`: `fit`, the estimator and then its goodness-of-fit check.

Cycle extraction from a trace (`stickslip._extract`) stands beside this package.
"""
