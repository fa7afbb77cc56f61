"""The slip-phase solvers as diffrax solvers."""

import json

import equinox as eqx
import numpy as np
import pytest
import scipy.integrate
import scipy.linalg
from conftest import new_process

from stickslip import EulerMaruyama, ExactGaussian, _rng
from stickslip._jax import jax, jnp
from stickslip._model import to_arrays
from stickslip._solver import PathwiseBrownian, SlipTerm, exact

# The solvers run as the simulator runs them, inside compiled code: one compilation per
# function and shape instead of one per primitive and shape (op by op: 12 s of a cold run).
transition = jax.jit(exact.transition)
psd_factor = jax.jit(exact.psd_factor)
# (Give it the step as an array: a Python float is a static argument, one compilation per step.)
traced_solver = eqx.filter_jit(ExactGaussian)
dense_nodes = eqx.filter_jit(lambda solver, m, y0, y1, h: solver.dense_nodes(m, y0, y1, h))

A = np.array([[0.0, 1.0, 0.0], [-1.0, -0.1, 1.0], [0.0, 0.0, -10.0]])
b = np.array([0.1, -0.2, 0.0])
B = np.array([[0.0], [0.0], [np.sqrt(0.8) * 10]])


def test_transition_against_quadrature():
    h = 0.07
    Phi, c, Sigma = (
        np.asarray(a) for a in transition(jnp.asarray(A), jnp.asarray(b), jnp.asarray(B), h)
    )
    np.testing.assert_allclose(Phi, scipy.linalg.expm(A * h), rtol=1e-13, atol=1e-15)
    c_ref = scipy.integrate.quad_vec(lambda s: scipy.linalg.expm(A * s) @ b, 0, h, epsabs=1e-15)[0]
    np.testing.assert_allclose(c, c_ref, rtol=1e-10, atol=1e-16)
    S_ref = scipy.integrate.quad_vec(
        lambda s: scipy.linalg.expm(A * s) @ B @ B.T @ scipy.linalg.expm(A * s).T,
        0,
        h,
        epsabs=1e-18,
    )[0]
    np.testing.assert_allclose(Sigma, S_ref, rtol=1e-9, atol=1e-18)


def test_psd_factor_handles_tiny_and_zero_variances():
    _, _, Sigma = transition(jnp.asarray(A), jnp.asarray(b), jnp.asarray(B), 0.005)
    L = np.asarray(psd_factor(Sigma))
    np.testing.assert_allclose(L @ L.T, np.asarray(Sigma), rtol=1e-9, atol=1e-22)
    Z = np.asarray(psd_factor(jnp.zeros((3, 3))))
    assert np.all(Z == 0)


def _setup(Langevin, solver, n, tau=0.1):
    model = to_arrays(Langevin(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=tau))
    key = _rng.stream_key(_rng.seed_key(0), _rng.STEP)
    path = np.arange(n, dtype=np.uint32)
    dt = np.asarray(0.01)
    control = PathwiseBrownian(key, path, dt, solver.noise_dim(model))
    X0 = np.tile(np.asarray(model.onset_state(None))[:, None], (1, n))
    return model, SlipTerm(model, control), (X0, None)


@eqx.filter_jit
def _first_step(solver, terms, y0, model, t0, t1):
    """One step of `solver` from `y0`, and the control's `(h, dW)` over it."""
    state = solver.init(terms, t0, t1, y0, model)
    return solver.step(terms, t0, t1, y0, model, state, False)[0][0], terms.contr(t0, t1)


def test_host_built_solver_equals_the_traced_one(Langevin):
    """The simulator builds its exact solver in NumPy (`host=True`): the same tables as the
    traced build, which the tests below check against the transition law."""
    m = Langevin(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)
    lg = m.linear_gaussian()
    for h in (0.01, 0.7, 5.0):
        traced = traced_solver(lg.A, lg.b, lg.B, jnp.asarray(h), nodes=16)  # one compilation
        host = ExactGaussian(lg.A, lg.b, lg.B, h, nodes=16, host=True)
        for name in ("Phi", "c", "node_Phi", "node_c", "node_G", "node_dG"):
            a, b = np.asarray(getattr(traced, name)), getattr(host, name)
            assert isinstance(b, np.ndarray)
            np.testing.assert_allclose(
                b, a, rtol=1e-12, atol=1e-14 * np.max(np.abs(a)), err_msg=name
            )
        LL = lambda s: np.asarray(s.L) @ np.asarray(s.L).T  # the factor's sign is free
        np.testing.assert_allclose(LL(host), LL(traced), rtol=1e-12, atol=1e-300)


def test_exact_step_has_the_transition_law(Langevin):
    n, h = 200_000, 0.01
    m = Langevin(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)
    lg = m.linear_gaussian()
    solver = traced_solver(lg.A, lg.b, lg.B, jnp.asarray(h))  # (8 nodes: as the tests below)
    model, terms, y0 = _setup(Langevin, solver, n)
    X1 = np.asarray(_first_step(solver, terms, y0, model, 0.0, 1.0)[0])
    Phi, c, Sigma = (np.asarray(a) for a in transition(lg.A, lg.b, lg.B, h))
    mean = Phi @ np.asarray(lg.m0) + c
    dev = X1 - mean[:, None]
    cov = dev @ dev.T / n
    sd = np.sqrt(np.diag(Sigma))
    assert np.all(np.abs(dev.mean(axis=1)) < 4 * sd / np.sqrt(n))
    corr_err = (cov - Sigma) / np.outer(sd, sd)
    assert np.max(np.abs(corr_err)) < 4 * np.sqrt(2 / n)


def test_euler_maruyama_step(Langevin):
    """X1 = X0 + f(X0) h + G(X0) dW with the increments the control hands out for that step."""
    solver = EulerMaruyama()
    model, terms, y0 = _setup(Langevin, solver, 64)
    ours, (h, dw) = jax.tree.map(np.asarray, _first_step(solver, terms, y0, model, 3.0, 4.0))
    X0 = np.asarray(y0[0])
    x, v, eta = X0
    drift = np.stack([v, -x - 0.1 * v + eta, -eta / 0.1])
    diffusion = np.array([0.0, 0.0, np.sqrt(0.8) / 0.1])[:, None] * dw
    np.testing.assert_allclose(ours, X0 + drift * h + diffusion, rtol=1e-14, atol=1e-15)
    assert h == pytest.approx(0.01)
    # The increments of step 3 are the same whichever step they are drawn from (counters).
    again = np.asarray(eqx.filter_jit(lambda c: c.evaluate(3.0, 4.0))(terms.control))
    np.testing.assert_array_equal(again, dw)


# 2 nodes in the slow tier (7 s cold): 8 nodes runs the same check in the default one
@pytest.mark.parametrize("nodes", [pytest.param(2, marks=pytest.mark.slow), 8])
def test_bridge_mean_nodes(Langevin, nodes):
    """Node values are E[X(s) | X_k, X_{k+1}], checked against Gaussian conditioning written
    out independently in NumPy; with no noise they are the exact flow."""
    h = 0.02
    m = Langevin(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)
    lg = m.linear_gaussian()
    solver = traced_solver(lg.A, lg.b, lg.B, jnp.asarray(h), nodes=nodes)
    rng = np.random.default_rng(0)
    y0 = rng.normal(size=(3, 5))
    y1 = rng.normal(size=(3, 5))
    values, slopes = (
        np.asarray(a) for a in dense_nodes(solver, m, jnp.asarray(y0), jnp.asarray(y1), h)
    )
    np.testing.assert_array_equal(values[0], y0)
    np.testing.assert_array_equal(values[-1], y1)
    An, Bn = np.asarray(lg.A), np.asarray(lg.B)
    for j in range(1, nodes):
        s = h * j / nodes
        P1, S1 = scipy.linalg.expm(An * s), _cov(An, Bn, s)
        P2, S2 = scipy.linalg.expm(An * (h - s)), _cov(An, Bn, h - s)
        # X(s) = P1 y0 + e1, X(h) = P2 X(s) + e2: condition X(s) on X(h) = y1.
        mean_s, cov_s_h = P1 @ y0, S1 @ P2.T
        cov_h = P2 @ S1 @ P2.T + S2
        expected = mean_s + cov_s_h @ np.linalg.solve(cov_h, y1 - P2 @ mean_s)
        np.testing.assert_allclose(values[j], expected, rtol=1e-7, atol=1e-9)
    # Slopes are the time derivative of the node values (finite differences of a fine solver).
    fine = traced_solver(lg.A, lg.b, lg.B, h, nodes=64)
    fv, fs = (np.asarray(a) for a in dense_nodes(fine, m, jnp.asarray(y0), jnp.asarray(y1), h))
    fd = (fv[2:] - fv[:-2]) / (2 * h / 64)
    np.testing.assert_allclose(fd, fs[1:-1], rtol=2e-3, atol=2e-3 * np.abs(fs).max())


def _cov(A, B, t):
    d = A.shape[0]
    M = np.block([[-A, B @ B.T], [np.zeros((d, d)), A.T]]) * t
    E = scipy.linalg.expm(M)
    return E[d:, d:].T @ E[:d, d:]


def test_noise_free_nodes_are_the_flow(Langevin):
    h = 0.05
    m = Langevin(omega0=1.0, zeta=0.1, D=0.0, v_b=1.0, x0=1.0, tau=0.1)
    lg = m.linear_gaussian()
    solver = traced_solver(lg.A, lg.b, lg.B, jnp.asarray(h), nodes=8)
    y0 = np.array([[1.0], [1.0], [0.0]])
    y1 = scipy.linalg.expm(np.asarray(lg.A) * h) @ y0
    values, slopes = (
        np.asarray(a) for a in dense_nodes(solver, m, jnp.asarray(y0), jnp.asarray(y1), h)
    )
    for j in range(9):
        flow = scipy.linalg.expm(np.asarray(lg.A) * h * j / 8) @ y0
        np.testing.assert_allclose(values[j], flow, rtol=1e-13, atol=1e-14)
        np.testing.assert_allclose(slopes[j], np.asarray(lg.A) @ flow, rtol=1e-12, atol=1e-14)


@pytest.mark.parametrize("dt", [0.2, 0.8])
def test_results_move_smoothly_with_the_parameters(dt):
    """Common random numbers: the same seed at D and D (1 + 1e-12) gives the same slips to
    ~1e-12. The step covariances' factors were eigenvector-based, whose column signs LAPACK
    may flip under a last-bit change: 99.8 % of slip times then moved (median 1e-3 at dt 0.2,
    0.1 at dt 0.8), which made the fit's simulated likelihood rough."""
    import stickslip as ss

    Model = ss.get_model("langevin")
    base = dict(omega0=1.0, zeta=0.1, v_b=1.0, x0=1.0, tau=0.1)
    a = ss.simulate(Model(D=0.4, **base), 2000, dt, 30.0, seed=3)
    b = ss.simulate(Model(D=0.4 * (1 + 1e-12), **base), 2000, dt, 30.0, seed=3)
    both = np.isfinite(a.slip_time) & np.isfinite(b.slip_time)
    assert np.array_equal(both, np.isfinite(a.slip_time))
    assert np.max(np.abs(a.slip_time[both] - b.slip_time[both])) < 1e-8
    assert np.max(np.abs(a.slip_distance[both] - b.slip_distance[both])) < 1e-8


CARRIED = """
import hashlib, json, pathlib, sys
import numpy as np
import jax
if sys.argv[1] == "carried":  # the paths other backends take, traced on this CPU
    jax.default_backend = lambda: "gpu"
import stickslip as ss
from stickslip import _compile
_compile.SHIPPED = pathlib.Path(sys.argv[2])  # none: the shipped traces are the CPU's paths
m = ss.get_model("langevin")(omega0=1.0, zeta=0.1, D=0.4, v_b=1.0, x0=1.0, tau=0.1)
runs = [ss.simulate(m, 3000, 1.6, 30.0, seed=3), ss.simulate(m, 3000, 0.1, 30.0, seed=4),
        ss.simulate(m, 2000, 0.05, 30.0, seed=5, solver="euler")]
print(json.dumps(dict(info=ss.cache_info(), digests=[hashlib.sha256(np.nan_to_num(np.stack(
    [e.slip_time, e.stick_time, e.slip_distance])).tobytes()).hexdigest() for e in runs])))
"""


@pytest.mark.slow
def test_noise_drawn_in_the_step_or_carried_gives_the_same_ensembles(tmp_path):
    """On a CPU the slip solvers and the refinement draw their noise where it is used, in a
    branch of their own; on other backends a step (or a level) ahead, carried in the loop
    (`AbstractSlipSolver.control`, `bridge.refine_levels`). Both are keyed by path, step
    and tree node, so the ensembles are the same to the last bit: the carried paths are
    checked here by tracing them on the CPU (a new process each, a cache of its own, no
    shipped traces: those hold the CPU's paths)."""
    (tmp_path / "none").mkdir()
    got = {
        mode: json.loads(
            new_process(CARRIED, tmp_path / mode, mode, tmp_path / "none", timeout=900)
        )
        for mode in ("here", "carried")
    }
    for run in got.values():
        assert run["info"]["shipped_loaded"] == 0 and run["info"]["traces"] > 0
    assert got["here"]["digests"] == got["carried"]["digests"]
