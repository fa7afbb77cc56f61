"""The propagators of a linear SDE (`stickslip._linear`) against closed forms and SciPy."""

import numpy as np
import pytest
from scipy import integrate, linalg

from stickslip import _linear

LAGS = np.concatenate([[0.0, 1e-6, 1e-3], np.geomspace(0.01, 60.0, 40)])


def _ou(a, s):
    """Scalar OU dX = -a X dt + s dW as 1 x 1 matrices, and its closed forms."""
    A, b, B = np.array([[-a]]), np.array([0.5]), np.array([[s]])
    closed = (
        np.exp(-a * LAGS),
        -np.expm1(-a * LAGS) / a,
        -(s**2) * np.expm1(-2.0 * a * LAGS) / (2.0 * a),
    )
    return (A, b, B), closed


@pytest.mark.parametrize("fn", ["propagators_host", "propagators_many"])
@pytest.mark.parametrize("a", [0.3, 10.0, 300.0])
def test_scalar_ou_is_its_closed_form(fn, a):
    """Phi = e^{-a t}, Phi1 = (1 - e^{-a t}) / a, Sigma = s^2 (1 - e^{-2 a t}) / (2 a), c =
    Phi1 b, from lags far below to far above the relaxation time (no doubling to ~20)."""
    (A, b, B), (phi, phi1, sig) = _ou(a, 1.7)
    Phi, Phi1, c, Sig = getattr(_linear, fn)(A, b, B, LAGS)
    np.testing.assert_allclose(Phi[:, 0, 0], phi, rtol=1e-11, atol=1e-300)
    np.testing.assert_allclose(Phi1[:, 0, 0], phi1, rtol=1e-13)
    np.testing.assert_allclose(c[:, 0], phi1 * 0.5, rtol=1e-13)
    np.testing.assert_allclose(Sig[:, 0, 0], sig, rtol=1e-13)


def test_langevin_drift_against_scipy():
    """The paper's linear model with OU friction noise (a damped oscillator driven by a
    fast noise): Phi against `scipy.linalg.expm`, Phi1 and Sigma against quadrature of their
    integrals; `propagators_many` equal to `propagators_host` to rounding."""
    A = np.array([[0.0, 1.0, 0.0], [-1.0, -0.2, 1.0], [0.0, 0.0, -10.0]])
    b, B = np.array([0.0, 1.0, 0.0]), np.array([[0.0], [0.0], [np.sqrt(2 * 0.4) * 10.0]])
    lags = np.array([1e-4, 0.05, 0.7, 3.0, 13.0])
    many = _linear.propagators_many(A, b, B, lags)
    host = _linear.propagators_host(A, b, B, lags)
    for x, y in zip(many, host, strict=True):
        np.testing.assert_allclose(x, y, rtol=1e-12, atol=1e-14 * np.abs(y).max())
    for i, t in enumerate(lags):
        np.testing.assert_allclose(many[0][i], linalg.expm(A * t), rtol=1e-11, atol=1e-14)
        phi1 = integrate.quad_vec(lambda s: linalg.expm(A * s), 0.0, t, epsabs=1e-14)[0]
        np.testing.assert_allclose(many[1][i], phi1, rtol=1e-9, atol=1e-13)
        sig = integrate.quad_vec(
            lambda s: linalg.expm(A * s) @ B @ B.T @ linalg.expm(A.T * s), 0.0, t,
            epsabs=1e-13, epsrel=1e-12, limit=400,
        )[0]  # fmt: skip
        np.testing.assert_allclose(many[3][i], sig, rtol=1e-9, atol=1e-12)
    # the shapes follow the lags': a scalar lag gives the bare matrices
    shapes = [x.shape for x in _linear.propagators_many(A, b, B, 0.3)]
    assert shapes == [(3, 3), (3, 3), (3,), (3, 3)]
