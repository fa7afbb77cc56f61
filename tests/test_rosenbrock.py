"""The noisy creeping slider's stepper (`rosenbrock`) against closed forms: a linear motion
forced by noise that is linear over each step, solved exactly by a matrix exponential."""

import numpy as np
import pytest
from scipy.linalg import expm

from stickslip._jax import jax, jnp
from stickslip._simulate import rosenbrock


class _Linear:
    """y' = A y + B xi(t): a stand-in with what the stepper reads of a model."""

    noise_dim = 1

    def __init__(self, A, B):
        self.A, self.B = jnp.asarray(A), jnp.asarray(B)

    def drift(self, y):
        return self.A @ y

    def diffusion(self, y):
        return self.B


def _exact(A, B, y0, h, xi0, xi1):
    """y(h) of y' = A y + B (xi0 + (xi1 - xi0) t / h), by the exponential of the system
    augmented with the forcing's constant and slope."""
    d = len(y0)
    M = np.zeros((d + 2, d + 2))
    M[:d, :d] = A
    M[:d, d] = B[:, 0] * xi0
    M[:d, d + 1] = B[:, 0] * (xi1 - xi0) / h
    M[d + 1, d] = 1.0  # s' = 1 (the time), c' = 0 (the constant)
    return (expm(M * h) @ np.r_[y0, 1.0, 0.0])[:d]


@pytest.mark.parametrize("stiff", [1.0, 1e4])
def test_ros2_is_of_second_order_under_a_ramped_forcing(stiff):
    """Global error over [0, 1] in N steps with the forcing ramped over each step (a
    different slope every step, as the noise's grid makes it): falls about 4 times as N
    doubles (order 2), also with a stiff mode (h * stiff up to 10^3: L-stable). Without
    the forcing's own term (the autonomous form) the stiff case fell 2.0 times a
    halving: order 1."""
    A = np.array([[-1.0, 2.0], [-2.0, -stiff]])
    B = np.array([[0.0], [3.0]])
    model = _Linear(A, B)
    step = jax.jit(lambda y, h, a, b: rosenbrock.ros2(model, y, h, a, b))
    rng = np.random.default_rng(0)
    nodes = rng.standard_normal(65)
    errors = []
    for n in (32, 64, 128):
        h = 1.0 / n
        xi = np.interp(np.arange(n + 1) * h, np.linspace(0, 1, 65), nodes)
        y = y_ref = np.array([1.0, 0.5])
        for i in range(n):
            y = np.asarray(step(jnp.asarray(y), h, xi[i : i + 1], xi[i + 1 : i + 2]))
            y_ref = _exact(A, B, y_ref, h, xi[i], xi[i + 1])
        errors.append(np.max(np.abs(y - y_ref)))
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    assert np.all(np.isfinite(errors))
    assert np.all(ratios > 3.3), (errors, ratios)


def test_steps_end_at_the_grid_nodes_and_keep_the_noise():
    """`dense` on y' = -y + xi (xi the grid's noise, linear between nodes) against the
    exact solution of that same forcing, node by node: the steps follow the grid (no
    kink inside a step), so the error is the tolerance's, not the grid's."""
    model = _Linear(np.array([[-1.0]]), np.array([[1.0]]))
    h, n = 0.01, 200
    key = jax.random.key_data(jax.random.key(3))
    z = np.array([float(rosenbrock.node(key, jnp.asarray(j, jnp.int64), 1)[0])
                  for j in range(n + 1)])  # fmt: skip
    xi = z / np.sqrt(h)
    ts = h * np.arange(0, n + 1, 5) + 0.003  # samples off the nodes: steps end at both
    ys = np.asarray(rosenbrock.dense(model, jnp.asarray([[0.7]]), jnp.asarray(key)[:, None],
                                     jnp.asarray(h), jnp.asarray(ts[:-1]), 1e-7, 1e-7,
                                     100_000))[:, 0, 0]  # fmt: skip
    # exact: from ts[0], across each piece of the piecewise-linear forcing
    y, t, ref = 0.7, ts[0], [0.7]
    for t_next in ts[1:-1]:
        while t < t_next - 1e-15:
            j = int(np.floor(t / h + 1e-12))
            t1 = min((j + 1) * h, t_next)
            x0 = np.interp(t, h * np.arange(n + 1), xi)
            x1 = np.interp(t1, h * np.arange(n + 1), xi)
            y = _exact(np.array([[-1.0]]), np.array([[1.0]]), np.array([y]), t1 - t, x0, x1)[0]
            t = t1
        ref.append(y)
    assert np.max(np.abs(ys - np.array(ref))) < 1e-5
