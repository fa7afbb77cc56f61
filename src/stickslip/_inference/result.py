"""`FitResult`: what `fit` returns (estimate, intervals, diagnostics, goodness of fit)."""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from .diagnostics import FitDiagnostics
from .forward import simulate_values
from .surface import DESIGN_STEP


@dataclasses.dataclass(frozen=True)
class FitResult:
    """The result of `fit`.

    - `estimate`, `ci`: the maximum simulated-likelihood estimate and 95 % intervals of
      each free parameter;
    - `log_likelihood`: at the estimate (of the data's transformed values plus the
      Jacobian of the log scale: a density of the data themselves);
    - `method`: what was done, in words;
    - `diagnostics`: a `FitDiagnostics` (also read as a mapping, `diagnostics["n_sim"]`):
      the settings (`n_sim`, `dt`, `t_max`, `seed`, bandwidths, `measurement`: the data's
      `Measurement`, `None` for per-cycle values, `box`: the search box), the covariance
      and Hessian (fit coordinates), every evaluated point, the evaluations and seconds
      spent, `optimizer` (Nelder-Mead's evaluations and cap), `design` (a `Design`: the
      axes clipped at the box, whether the polynomial had a vertex, its `centre`, `steps`,
      `points` and their `values` at both `seeds`, in fit coordinates, and, where small
      enough, the cycles simulated there, which `compare_fits` reuses), `mc_noise` (the
      second seed, the Monte Carlo sd of the estimate against its standard error, the
      `n_sim` advised), `zero_fraction` (of each duration column), and `warnings` (each
      also issued as a one-line `UserWarning`);
    - `goodness`: the `GoodnessOfFit` of the fitted model against the data (`fit`'s
      `check=True`), and `p_values` from it (`None` with `check=False`).
    """

    estimate: dict[str, float]
    ci: dict[str, tuple[float, float]]
    log_likelihood: float
    method: str
    diagnostics: FitDiagnostics
    data: dict[str, np.ndarray] = dataclasses.field(repr=False)
    model: Any = dataclasses.field(repr=False)
    goodness: Any = dataclasses.field(default=None, repr=False)

    def __post_init__(self):
        if not isinstance(self.diagnostics, FitDiagnostics):  # a mapping of its fields
            object.__setattr__(self, "diagnostics", FitDiagnostics.from_mapping(self.diagnostics))

    def __setstate__(self, state: dict) -> None:
        """Unpickled (a fit kept from an earlier version held its diagnostics as a dict)."""
        diagnostics = state.get("diagnostics")
        if diagnostics is not None and not isinstance(diagnostics, FitDiagnostics):
            state = {**state, "diagnostics": FitDiagnostics.from_mapping(diagnostics)}
        self.__dict__.update(state)

    @property
    def p_values(self) -> dict[str, float] | None:
        """`{observable: p}`, the simulation-calibrated goodness-of-fit p-value of each
        fitted column (`goodness_of_fit`), and `"joint"`, all columns at once, when there
        are several; `None` when the fit ran with `check=False`. Small: the data are unlike
        the fitted model's (below `ALPHA` = 0.01 the fit warned)."""
        if self.goodness is None:
            return None
        out = dict(self.goodness.p_values)
        if len(out) > 1:
            out["joint"] = self.goodness.p_value
        return out

    def summary(self) -> str:
        lines = [f"{self.method}", f"log-likelihood {self.log_likelihood:.2f}"]
        for k, v in self.estimate.items():
            lo, hi = self.ci[k]
            shown = f"[{lo:.4g}, {hi:.4g}]" if np.isfinite([lo, hi]).all() else "none (warnings)"
            lines.append(f"  {k} = {v:.4g}   95 % interval {shown}")
        if self.p_values is not None:
            shown = ", ".join(f"{k} p = {p:.3g}" for k, p in self.p_values.items())
            lines.append(f"goodness of fit ({self.goodness.n_rep} replicates): {shown}")
        for run in self.diagnostics.runs or ():
            shown = ", ".join(f"{k} p = {p:.3g}" for k, p in run.get("p_values", {}).items())
            why = f" ({run['unresolved']})" if run.get("unresolved") else ""
            lines.append(f"  {run['name']}: k = {run['stiffness']:.6g} N/m, V = "
                         f"{run['v_b']:.4g} m/s, {run['cycles']} cycles"
                         + (f"; KS {shown}{why}" if shown else ""))  # fmt: skip
        lines += [f"warning: {w}" for w in self.diagnostics.warnings]
        return "\n".join(lines)

    def predict(self, run=None, *, stiffness=None, v_b=None, n_sim=None, seed=None):
        """What this fit predicts for a slider at another spring and driving speed, with
        the physical parameters it estimated (an effective mass, damping, noise and
        threshold in SI, by the `Slider` the fit was given as `scales`).

        - `run`: a measured run's `Cycles` (a force trace, from `extract_cycles`): its
          stiffness and loading speed, its measurement, and a predictive p-value per
          observable against its cycles;
        - `stiffness` (N/m), `v_b` (m/s): without a run, both; with one, to override its;
        - `n_sim`, `seed`: the simulation (default the fit's `n_sim`, its seed plus 1).

        **Returns:** a `Prediction` (`regime`, `cycles` in SI, `p_values`, `summary()`).
        Needs a fit made with `scales=Slider(...)`, or a creeping slider's fit (in SI: its
        fitted model at the stiffness and speed, the run's given `v_b` rather than its
        sticks' slope, which creep; its stationary motion after a burn-in; without a
        run, through a noise-free force trace sampled at a fortieth of its slip)."""
        from .predict import predict

        return predict(self, run, stiffness=stiffness, v_b=v_b, n_sim=n_sim, seed=seed)

    def save(self, path) -> None:
        """Write this fit to `path` as one JSON file (`stickslip.load_fit` reads it back):
        the model and its arguments, the estimate and intervals, the data's columns, the
        measurement, the settings and diagnostics, the goodness of fit. The cycles
        simulated at the design points are not kept (`compare_fits` simulates them again,
        the same cycles). A file already at `path` is replaced whole."""
        from .saved import save_fit

        save_fit(self, path)

    def simulated(self, n_sim: int | None = None, seed: int | None = None) -> dict:
        """Cycles of the fitted model (at the estimate) as the data see them: through the
        data's measurement for a `Cycles` (sampled, noisy, extracted with its settings),
        per-cycle values otherwise; in the units the fit worked in (the model's), with the
        data's columns. `n_sim` (default the fit's) simulated cycles, `seed` (default the
        fit's) their seed: for a predictive check take one other than the fit's, so that
        the comparison does not reuse the draws the estimate was tuned on."""
        d = self.diagnostics
        sim = simulate_values(self.model, d.n_sim if n_sim is None else int(n_sim), d.dt,
                        d.t_max, d.seed if seed is None else int(seed),
                        d.measurement)  # fmt: skip
        return {k: np.asarray(sim[k], float) for k in self.data}

    def plot(self, path=None, n_sim: int | None = None):
        """Data against the fitted model (a histogram per quantity and the simulated
        density at the estimate, its goodness-of-fit p-value in the title), and the
        log-likelihood along each free parameter (the evaluated points and the fitted
        quadratic). Returns the figure; saves it to `path`."""
        import matplotlib

        if path is not None:
            matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        kinds = list(self.data)
        free = list(self.estimate)
        fig, axes = plt.subplots(
            1, len(kinds) + len(free), figsize=(3.6 * (len(kinds) + len(free)), 3.2)
        )
        axes = np.atleast_1d(axes)
        d = self.diagnostics
        sim = self.simulated(n_sim)
        for ax, k in zip(axes, kinds, strict=False):
            x = self.data[k]
            edges = np.histogram_bin_edges(x, bins=min(60, max(10, x.size // 50)))
            ax.hist(x, edges, density=True, alpha=0.5, label=f"data ({x.size})")
            ax.hist(sim[k], edges, density=True, histtype="step", lw=1.5, label="fitted model")
            ax.set_xlabel(k)
            ax.legend(fontsize=7)
            if self.p_values is not None:
                ax.set_title(f"{k}: p = {self.p_values[k]:.3g}", fontsize=9)
        pts = np.array([p[0] for p in d.points])
        ll = np.array([p[1] for p in d.points])
        for i, (ax, name) in enumerate(zip(axes[len(kinds) :], free, strict=True)):
            u = d.to_fit(name, pts[:, i])
            ax.plot(u, ll, ".", ms=3, color="0.6", label="evaluated")
            u0 = d.to_fit(name, self.estimate[name])
            grid = np.linspace(u0 - 3 * DESIGN_STEP, u0 + 3 * DESIGN_STEP, 50)
            H = np.asarray(d.hessian)
            ax.plot(
                grid, self.log_likelihood + 0.5 * H[i, i] * (grid - u0) ** 2, "-", label="quadratic"
            )
            ax.set_ylim(self.log_likelihood - 20, self.log_likelihood + 2)
            ax.set_xlabel(f"{d.scales[name]} {name}")
            ax.set_ylabel("log-likelihood")
            ax.legend(fontsize=7)
        fig.tight_layout()
        if path is not None:
            fig.savefig(path, dpi=110)
            plt.close(fig)
        return fig
