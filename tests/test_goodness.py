"""`goodness_of_fit`: a simulation-calibrated p-value per observable (issue 40, item 5).
Data are simulated with seeds the fit and the test do not use; seeds fixed in advance."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy import stats

import stickslip as ss
from stickslip import AndersonDarling
from stickslip._inference.forward import simulate_values
from stickslip._inference.goodness import _pit, goodness_of_fit
from stickslip._inference.likelihood import cycle_log_likelihood

BASE = dict(omega0=1.0, zeta=0.1, v_b=1.0, x0=1.0)
TRUTH = dict(D=0.4, tau=0.1)
FIXED = {**BASE, "tau": TRUTH["tau"]}


def cycles(n, seed, **params):
    """`n` per-cycle values (slips of positive length that ended) of the Langevin model."""
    model = ss.get_model("langevin")(**{**BASE, **TRUTH, **params})
    sim = simulate_values(model, int(n * 1.3) + 100, 0.2, 200.0, seed)
    assert sim["slip_time"].size >= n
    return {k: v[:n] for k, v in sim.items()}


def fit_d(data, check=False):
    """D free, the rest known: 5000 simulated cycles per point (the fast tier's size);
    without fit's own check unless asked (most tests call `goodness_of_fit` themselves)."""
    return ss.fit(
        "langevin", data, free={"D": (0.05, 2.0)}, fixed=FIXED, seed=7, n_sim=5000, check=check
    )


def test_randomised_pit_is_uniform_with_an_atom_and_sees_a_wrong_atom():
    """Stick times with a point mass at zero: the randomised transform of data from the
    reference's own law is uniform (KS against uniform), a wrong zero share is not."""
    rng = np.random.default_rng(41)

    def sticks(n, zero_share):
        return np.where(rng.random(n) < zero_share, 0.0, rng.exponential(1.0, n))

    reference = np.sort(sticks(200_000, 0.38))
    same = _pit(sticks(3000, 0.38), [reference], [1.0], rng)
    assert stats.kstest(same, "uniform").pvalue > 1e-3  # fails 1 in 1000 under uniformity
    fewer = _pit(sticks(3000, 0.30), [reference], [1.0], rng)
    assert stats.kstest(fewer, "uniform").pvalue < 1e-6
    # without the randomisation every zero would sit at one value, F(0) = 0.38
    assert np.mean(same < 0.19) == pytest.approx(0.19, abs=4 * np.sqrt(0.19 * 0.81 / 3000))


def test_anderson_darling_is_the_weighted_distance_of_its_definition():
    """A^2 = n * integral of (F_n(t) - t)^2 / (t (1 - t)) dt, by quadrature on a fine grid."""
    rng = np.random.default_rng(42)
    u = rng.beta(1.3, 1.0, 200) * 0.98 + 0.01
    t = np.linspace(0.0, 1.0, 2_000_001)[1:-1]
    fn = np.searchsorted(np.sort(u), t, "right") / u.size
    want = u.size * np.trapezoid((fn - t) ** 2 / (t * (1 - t)), t)
    assert AndersonDarling()(u) == pytest.approx(want, rel=1e-3)


def test_the_other_statistics_are_scipys():
    """Cramer-von Mises and Kolmogorov-Smirnov against uniform: SciPy's own statistics."""
    rng = np.random.default_rng(43)
    for u in (rng.random(37), rng.beta(1.3, 1.0, 500) * 0.98 + 0.01):
        want = stats.cramervonmises(u, "uniform").statistic
        assert ss.CramerVonMises()(u) == pytest.approx(want, rel=1e-12)
        assert ss.KolmogorovSmirnov()(u) == pytest.approx(stats.kstest(u, "uniform").statistic)


def test_a_ks_test_of_dependent_rows_keeps_its_level():
    """Runs of 300 rows of a Gaussian AR(1) of coefficient 0.6 (successive cycles of a
    slider with memory are as dependent) against a large sample of their true marginal
    law: the plain two-sample KS test rejects far more often than its level, the test at
    the samples' effective sizes (`statistics.dependent_ks`) at about its level (400 runs:
    the binomial sd of a 5 % rate is 1.1 %); on independent rows it is the plain test."""
    from scipy import signal

    from stickslip._inference.statistics import dependence_factor, dependent_ks

    rng = np.random.default_rng(12)
    phi, n, runs = 0.6, 300, 400
    truth = rng.normal(0.0, 1.0 / np.sqrt(1.0 - phi**2), 20_000)
    plain, dependent = [], []
    for _ in range(runs):
        x = signal.lfilter([1.0], [1.0, -phi], rng.normal(size=n + 100))[100:]
        plain.append(stats.ks_2samp(x, truth).pvalue)
        dependent.append(dependent_ks(x, truth))
    sd = np.sqrt(0.05 * 0.95 / runs)
    assert np.mean(np.array(plain) < 0.05) > 0.05 + 5 * sd  # the plain test's fault
    assert abs(np.mean(np.array(dependent) < 0.05) - 0.05) < 3 * sd
    iid = rng.normal(size=300)
    assert dependence_factor(iid) == 1.0
    assert dependent_ks(iid, truth) == pytest.approx(stats.ks_2samp(iid, truth).pvalue, abs=0.01)


class Watson(ss.Statistic):
    """A user's statistic (Watson's U^2, invariant to rotations of the circle), counting
    its calls."""

    name, symbol = "Watson distance", "U^2"
    calls = 0

    def __call__(self, u):
        Watson.calls += 1
        u = np.sort(u)
        n = u.size
        w2 = 1 / (12 * n) + np.sum((u - (2 * np.arange(1, n + 1) - 1) / (2 * n)) ** 2)
        return float(w2 - n * (np.mean(u) - 0.5) ** 2)


@pytest.mark.slow  # three statistics, 200 replicates each, on the fit below
@pytest.mark.parametrize("statistic", [ss.CramerVonMises(), ss.KolmogorovSmirnov(), Watson()])
def test_every_statistic_rejects_exponential_slip_times(statistic):
    """The statistic is a choice: each rejects what no stick-slip model makes (exponential
    'slip times' of the model's own mean), and a user's class is called once for the data
    and once per replicate, its symbol in the summary."""
    mean = np.mean(cycles(20_000, seed=99)["slip_time"])
    x = np.random.default_rng(5).exponential(mean, 1500)
    r = fit_d({"slip_time": x})
    Watson.calls = 0
    with pytest.warns(UserWarning, match="the data reject the model"):
        g = goodness_of_fit(r, n_rep=200, seed=3, statistic=statistic)
    assert g.p_values["slip_time"] < 0.01, g.summary()
    assert g.statistic is statistic and statistic.name in g.method
    assert f"slip_time: {statistic.symbol} = " in g.summary()
    if isinstance(statistic, Watson):
        assert Watson.calls == 1 + 200


@pytest.mark.slow  # a fit and its p-value check, ~10 s CPU; the default tier checks p-values below
def test_exponential_slip_times_are_rejected_with_a_warning_and_a_figure(tmp_path):
    """Exponential 'slip times' of the model's own mean slip time: no stick-slip model
    makes them, yet they get an estimate and an interval; `fit`'s check and
    `goodness_of_fit` both reject them."""
    mean = np.mean(cycles(20_000, seed=99)["slip_time"])
    x = np.random.default_rng(5).exponential(mean, 1500)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        r = fit_d({"slip_time": x}, check=True)
    # fit's own check: one plain warning, in the diagnostics too, and the p-value on r
    said = [str(w.message) for w in caught if "reject" in str(w.message)]
    assert len(said) == 1 and said[0].startswith("fit: the data reject the model: slip_time p")
    assert said[0].removeprefix("fit: ") in r.diagnostics["warnings"]
    assert r.p_values["slip_time"] < 0.01 and r.goodness.rejected
    with pytest.warns(UserWarning, match="the data reject the model: slip_time p = "):
        g = goodness_of_fit(r, n_rep=200, seed=3)
    assert g.p_values["slip_time"] < 0.01 and g.rejected
    assert g.p_value == g.p_values["slip_time"]
    assert all("\n" not in w for w in g.warnings)
    g.plot(tmp_path / "gof.png")
    assert (tmp_path / "gof.png").stat().st_size > 1000


# one set in the default tier, the others in slow (each is a fit plus 200 replicates)
@pytest.mark.parametrize(
    "seed", [11, pytest.param(12, marks=pytest.mark.slow), pytest.param(13, marks=pytest.mark.slow)]
)
def test_data_from_the_truth_are_not_rejected(seed):
    """Three data sets at the truth (each rejected by chance with probability 0.01)."""
    r = fit_d({"slip_time": cycles(1500, seed)["slip_time"]})
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        g = goodness_of_fit(r, n_rep=100, seed=3)
    assert g.p_values["slip_time"] >= 0.01 and not g.rejected, g.summary()
    assert not [w for w in caught if "reject" in str(w.message)]
    assert g.replicates["slip_time"].shape == (100,)


@pytest.mark.slow  # 10 s: two columns, two fits
def test_two_observables_at_the_truth_pass_and_without_their_zero_sticks_fail():
    """Slip and stick times of one set of cycles (stick times with their zero-length ones,
    the atom) fitted jointly: not rejected; the same cycles with the zero-length sticks
    dropped (as a user might, taking them for glitches) are, in both columns."""
    data = {k: v for k, v in cycles(1500, seed=21).items() if k in ("slip_time", "stick_time")}
    assert 0.2 < np.mean(data["stick_time"] == 0) < 0.6  # the atom is there to be tested
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        g = goodness_of_fit(fit_d(data), n_rep=200, seed=3)
    assert min(g.p_values.values()) >= 0.01 and g.p_value >= 0.01, g.summary()
    assert set(g.p_values) == {"slip_time", "stick_time"}
    kept = data["stick_time"] > 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        r = fit_d({k: v[kept] for k, v in data.items()})
    with pytest.warns(UserWarning, match="the data reject the model: slip_time p = .*stick_time"):
        g = goodness_of_fit(r, n_rep=200, seed=3)
    assert max(g.p_values.values()) < 0.01 and g.p_value < 0.01


def test_bad_arguments_are_one_line_naming_the_field(monkeypatch):
    with pytest.raises(ss.ParameterError, match="'result' must be a FitResult") as err:
        goodness_of_fit({"slip_time": np.ones(10)})
    assert "\n" not in str(err.value)
    r = fit_d({"slip_time": cycles(300, seed=23)["slip_time"]})
    assert r.p_values is None and r.goodness is None  # check=False
    with pytest.raises(ss.ParameterError, match="'check' must be True or False"):
        ss.fit("langevin", {"slip_time": cycles(300, seed=23)["slip_time"]}, {"D": (0.1, 1.0)},
               FIXED, check="yes")  # fmt: skip
    with pytest.raises(ss.ParameterError, match="'n_rep' must be >= 1"):
        goodness_of_fit(r, n_rep=0)
    with pytest.raises(ss.ParameterError, match="'statistic' must be a Statistic"):
        goodness_of_fit(r, statistic="anderson")
    with pytest.warns(UserWarning, match="no p-value is below 0.0196: take n_rep >= 100"):
        goodness_of_fit(r, n_rep=50, seed=3)
    # 99 replicates: the smallest p-value is 1/100, not below 0.01: still no verdict
    with pytest.warns(UserWarning, match="no p-value is below 0.01: take n_rep >= 100"):
        goodness_of_fit(r, n_rep=99, seed=3)
    # 10^6 replicates of 300 cycles are 2.24 GiB of values: refused before any is simulated
    monkeypatch.setenv("STICKSLIP_MEMORY_LIMIT", str(2**30))
    with pytest.raises(ss.ResourceError, match="'n_rep' needs about 2.24 GiB, past the limit"):
        goodness_of_fit(r, n_rep=10**6)


@pytest.mark.slow
def test_refit_runs_every_replicate_through_fit():
    r = fit_d({"slip_time": cycles(300, seed=24)["slip_time"]})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        g = goodness_of_fit(r, n_rep=2, seed=3, refit=True)
    assert "refitted" in g.method and np.all(np.isfinite(g.replicates["slip_time"]))
    assert g.p_values["slip_time"] in (1 / 3, 2 / 3, 1.0)


@pytest.mark.slow
def test_the_linearised_refit_matches_the_exact_one():
    """The default's replicates (one Newton step) and refitted ones (`fit` on each) have
    one distribution of the statistic: a two-sample KS test at 0.01 (40 refits)."""
    r = fit_d({"slip_time": cycles(1500, seed=25)["slip_time"]})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        linear = goodness_of_fit(r, n_rep=200, seed=4).replicates["slip_time"]
        exact = goodness_of_fit(r, n_rep=40, seed=5, refit=True).replicates["slip_time"]
    assert stats.ks_2samp(linear, exact).pvalue > 0.01, (np.median(linear), np.median(exact))


@pytest.mark.slow
def test_p_values_at_the_truth_are_uniform_over_40_sets():
    """Issue 40's acceptance: 40 data sets simulated at the truth (seeds 1000-1039), each
    fitted (seeds 2000-2039) with fit's own check (`FitResult.p_values`, its replicates
    seeded from the fit's seed: one seed for all would share one simulation error among the
    sets, and their p-values would not be independent); the p-values pass a KS test of
    uniformity at 0.01."""
    ps = []
    for s in range(40):
        data = {"slip_time": cycles(1500, 1000 + s)["slip_time"]}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            r = ss.fit("langevin", data, {"D": (0.05, 2.0)}, FIXED, seed=2000 + s, n_sim=5000)
        ps.append(r.p_values["slip_time"])
    assert stats.kstest(ps, "uniform").pvalue > 0.01, np.round(np.sort(ps), 3)


# -- fit's own check: FitResult.p_values -----------------------------------------------------
def test_fit_checks_itself_and_data_from_the_truth_pass():
    """`fit` with its default check, slip and stick times of 600 cycles at the truth (zero
    sticks in): a p-value per column and a joint one, each in (0, 1] and a multiple of
    1/(n_rep + 1) (a simulation-calibrated rank); none below 0.01 (at the truth each is with
    probability 0.01); in the summary and the figure's titles."""
    data = {k: v for k, v in cycles(600, seed=31).items() if k in ("slip_time", "stick_time")}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        r = ss.fit("langevin", data, {"D": (0.05, 2.0)}, FIXED, seed=17, n_sim=5000)
    assert isinstance(r.goodness, ss.GoodnessOfFit)
    assert set(r.p_values) == {"slip_time", "stick_time", "joint"}
    n_rep = r.goodness.n_rep
    for p in r.p_values.values():
        assert 0 < p <= 1 and p * (n_rep + 1) == pytest.approx(round(p * (n_rep + 1)))
    assert min(r.p_values.values()) >= 0.01, r.summary()
    assert not [w for w in caught if "reject" in str(w.message)]
    assert f"stick_time p = {r.p_values['stick_time']:.3g}" in r.summary()
    # a FitResult pickles (fits cross to and from worker processes: no closures in it),
    # and the copy draws the same figure
    import pickle

    copy = pickle.loads(pickle.dumps(r))
    assert copy.estimate == r.estimate and copy.p_values == r.p_values
    fig = copy.plot()
    titles = [ax.get_title() for ax in fig.axes]
    assert f"slip_time: p = {r.p_values['slip_time']:.3g}" in titles, titles
    import matplotlib.pyplot as plt

    plt.close(fig)

    # the per-cycle terms another fit or a held-out set is scored with
    terms = cycle_log_likelihood(r)
    assert terms.shape == (600,) and np.all(np.isfinite(terms))
    assert terms.sum() == pytest.approx(r.log_likelihood, rel=1e-12, abs=1e-9)
    far = cycle_log_likelihood(r, {"D": 3 * r.estimate["D"]})
    assert far.sum() < terms.sum() - 10, (far.sum(), terms.sum())
    held_out = {k: v for k, v in cycles(300, seed=32).items() if k in data}
    assert cycle_log_likelihood(r, data=held_out).shape == (300,)
    with pytest.raises(ss.ParameterError, match="'data' must have the fit's columns"):
        cycle_log_likelihood(r, data={"slip_time": held_out["slip_time"]})
    with pytest.raises(ss.ParameterError, match="'params\\['Q'\\]' is not a parameter"):
        cycle_log_likelihood(r, {"Q": 1.0})


@pytest.mark.slow  # 200 replicates evaluated both ways, ~20 s
def test_the_tabulated_one_step_matches_the_kernel_estimate_per_replicate():
    """The linearised bootstrap's one-step estimates from the shifted references' densities
    tabulated once for all replicates (`gradient_tables`) against the same Newton step from
    `_log_density`'s own kernel estimate on each replicate's grid (as before the tables):
    they differ by the binning alone, below 1 % of the replicates' scatter."""
    from stickslip._inference import goodness
    from stickslip._inference.likelihood import _log_density

    data = cycles(200, seed=41)
    r = fit_d({"slip_time": data["slip_time"]})
    setting = goodness.Setting.of(r)
    shifted = setting.shifted_references(5000, 5)
    reps = goodness.simulate_replicates(setting, 200, 20, 9)
    newton = setting.newton()

    def direct(rep):
        g = np.zeros(1)
        for j, ((plus, minus), step) in enumerate(shifted):
            h = setting.bandwidth["slip_time"]
            up = _log_density("slip_time", rep["slip_time"], plus["slip_time"], h)
            down = _log_density("slip_time", rep["slip_time"], minus["slip_time"], h)
            g[j] = (np.sum(up) - np.sum(down)) / step
        return newton @ g

    want = np.array([direct(rep) for rep in reps])
    tables = setting.gradient_tables(shifted, reps, r.data)
    got = np.array([setting.one_step(rep, tables, newton) for rep in reps])
    assert np.max(np.abs(got - want)) < 0.01 * np.std(want), (got - want, np.std(want))
