"""The model base classes that every friction model plugin implements: `FrictionModel` (one
block's hybrid stick/slip), with `LinearGaussian` for an exact slip phase, and `ChainModel` (a
chain of blocks that stick and slip one by one)."""

from __future__ import annotations

import abc
from typing import Any, ClassVar

import equinox as eqx
import numpy as np

from ._jax import jax, jnp


class LinearGaussian(eqx.Module):
    r"""Linear-Gaussian description of a slip phase.

    The slip-phase SDE is $dX = (A X + b)\,dt + B\,dW$ with additive noise; the crossing
    variable is the linear functional $c^\top X$ and the position $p^\top X$. At slip
    onset $X(0) \sim \mathcal{N}(m_0, P_0)$. The exact simulator and the exact
    crossing-statistics estimator both use it.

    **Arguments:**

    - `A`: drift matrix, shape `(d, d)`.
    - `b`: drift offset, shape `(d,)`.
    - `B`: noise matrix, shape `(d, m)`.
    - `crossing`: crossing functional $c$, shape `(d,)`.
    - `position`: position functional $p$, shape `(d,)`.
    - `m0`, `P0`: mean `(d,)` and covariance `(d, d)` of the state at slip onset.
    """

    A: Any
    b: Any
    B: Any
    crossing: Any
    position: Any
    m0: Any
    P0: Any


class FrictionModel(eqx.Module):
    r"""A stochastic friction model as a hybrid stick/slip system.

    A concrete model is a final class whose fields are its parameters, validated on
    construction (`__check_init__`) with a `ParameterError` naming the parameter. It states:

    - the **slip-phase SDE** $dX = f(X)\,dt + G(X)\,dW$: `state_names`, `noise_dim`,
      `drift` and `diffusion` (single path; the simulator vectorises). The slip phase is
      autonomous: time is measured from slip onset and does not enter $f$ or $G$;
    - the **crossing variable** `crossing(X)` and its `stick_level`: a slip ends at the first
      $t > 0$ with `crossing(X(t)) >= stick_level` (the stick). If the crossing variable is
      increasing at onset the slip has zero length (an immediate re-stick);
    - the **stick phase** in closed form: `stick_duration(X_stick, X_next)` from the state at
      the stick and the state the next slip starts from;
    - the **release rule**: `onset_state(key)`, the state at slip onset (it may be random,
      e.g. a random threshold or a random initial noise);
    - optionally **memory across cycles**: a model with `carries_state = True` says in
      `release(key, X_stick)` what the stick does to the state and which state the next slip
      starts from, so that successive cycles of `simulate_cycles` depend on each other
      (the default, `onset_state` and `stick_duration`, restarts every cycle afresh);
    - optionally `linear_gaussian()`, when the slip SDE is linear with additive noise: the
      simulator then steps exactly and the estimator is exact.
    - optionally `slip_phase()`, a plainer model with the same slip-phase methods, when the
      model's other fields matter only at release or in the stick phase: runs of both then
      share the simulator's compiled slip-phase programs.

    The defaults read the crossing variable and position from the state components named
    `"v"` and `"x"`, and give the stick phase of eq. (9): the position advances at the stick
    level (the driving speed) until it reaches the next threshold.
    """

    # -- slip-phase SDE ------------------------------------------------------------------
    @property
    @abc.abstractmethod
    def state_names(self) -> tuple[str, ...]:
        """Names of the state components, e.g. `("x", "v")`."""

    @property
    @abc.abstractmethod
    def noise_dim(self) -> int:
        """Number of independent Brownian motions driving the slip phase."""

    @abc.abstractmethod
    def drift(self, y):
        """Drift $f(X)$ of one path: shape `(d,)` from a state of shape `(d,)`."""

    @abc.abstractmethod
    def diffusion(self, y):
        """Diffusion $G(X)$ of one path: shape `(d, noise_dim)`."""

    # -- crossing and stick --------------------------------------------------------------
    @property
    @abc.abstractmethod
    def stick_level(self):
        """The level of the crossing variable at which the slip ends (e.g. $v_b$)."""

    def crossing(self, y):
        """The crossing variable of one path (default: the component named `"v"`)."""
        return y[self.state_names.index("v")]

    def position(self, y):
        """The position of one path (default: the component named `"x"`)."""
        return y[self.state_names.index("x")]

    def crossing_rate(self, y):
        """Drift part of d(crossing)/dt: the crossing variable's velocity where it is
        differentiable (default: by forward-mode differentiation along the drift)."""
        return jax.jvp(self.crossing, (y,), (self.drift(y),))[1]

    def crossing_noise(self, y):
        """Variance rate of the noise entering the crossing variable directly:
        $|\\nabla c^\\top G|^2$ (zero when the crossing variable is differentiable)."""
        grad = jax.grad(self.crossing)(y)
        return jnp.sum((grad @ self.diffusion(y)) ** 2)

    @property
    def crossing_is_smooth(self) -> bool:
        """True when no noise enters the crossing variable directly, so it is differentiable
        in time and has a finite upcrossing rate (Rice). Must be a Python bool, decided from
        the parameters; the default evaluates `crossing_noise` at a sample onset state."""
        y0 = self.onset_state(jax.random.key(0))
        return bool(self.crossing_noise(y0) == 0.0)

    def onset_state(self, key):
        """The state at slip onset, shape `(d,)`; `key` is a JAX PRNG key for random onsets."""
        raise NotImplementedError

    def stick_duration(self, y_stick, y_next):
        """Duration of the stick phase between a stick in state `y_stick` and the next slip
        onset in state `y_next` (eq. 9): $T_{st} = \\max(0, (x_0' - x_{sl}) / v_b)$.

        A stick that ends beyond the next threshold releases at once (zero stick time)."""
        gap = self.position(y_next) - self.position(y_stick)
        return jnp.maximum(gap, 0.0) / self.stick_level

    # Memory across cycles. False (the default): every slip starts from `onset_state`, whatever
    # the cycle before it did (the paper's sharp reset), and `release` is never called on the
    # simulator's hot path. A class attribute, so that the simulator decides it statically.
    carries_state: ClassVar[bool] = False

    def release(self, key, y_stick):
        r"""The stick phase of a model with memory: from the state `y_stick` at the stick to
        the onset of the next slip.

        **Arguments:**

        - `key`: the JAX PRNG key of the next cycle's release (the key `onset_state` would
          get for it), for what the stick draws afresh (a random threshold);
        - `y_stick`: the state at the stick, shape `(d,)`.

        **Returns:** `(stick_time, y_next)`: the stick's duration $T_{st} \ge 0$ and the state
        the next slip starts from, shape `(d,)`. Both must be traceable by JAX (closed form,
        a fixed number of iterations, or a `jax.lax` loop), as `drift` is.

        The default is memoryless: `y_next = onset_state(key)` and
        `stick_time = stick_duration(y_stick, y_next)`. The simulator calls it only for a
        model whose class sets `carries_state = True`; such a model states here how the
        stick evolves what it carries (a contact that ages, a threshold that grows with the
        time stuck) and may carry any state component into the next slip. `simulate`'s
        first-passage ensembles are unchanged in meaning: every path's first slip starts
        from `onset_state`; `Ensemble.stick_time` and `next_onset_state` come from here."""
        y_next = self.onset_state(key)
        return self.stick_duration(y_stick, y_next), y_next

    def linear_gaussian(self) -> LinearGaussian | None:
        """The linear-Gaussian description of the slip phase, or None (the default)."""
        return None

    def slip_phase(self) -> FrictionModel:
        """The model as the simulator's compiled slip-phase code sees it (default: itself).

        The stepping loop and the in-step location call only the slip-phase methods
        (`state_names`, `noise_dim`, `drift`, `diffusion`, `crossing`, `crossing_rate`,
        `crossing_noise`, `stick_level`); the release (`onset_state`), the stick phase and the
        linear-Gaussian description are always the model's own. A model whose other fields
        matter only at release or in the stick phase (a law of random thresholds) may return
        a plainer model whose slip-phase methods compute the same numbers: runs of both then
        share those compiled programs (one compilation instead of one per model class and
        law; the `random-threshold` plugin returns its `langevin` slip). The results are the
        same to the last bit; the model contract test checks the methods agree."""
        return self

    def onset_mixture(self, nodes: int = 32):
        """The law of the onset state as a mixture of Gaussians, for the exact estimator:
        `(m0s (K, d), P0s (K, d, d), weights (K,))`, weights summing to 1. The default is the
        single Gaussian `N(m0, P0)` of `linear_gaussian()`; a model with a non-Gaussian random
        onset (a random threshold) gives quadrature nodes of it, `nodes` of them."""
        lg = self.linear_gaussian()
        if lg is None:
            return None
        m0 = np.asarray(lg.m0, dtype=float)
        P0 = np.asarray(lg.P0, dtype=float)
        return m0[None], P0[None], np.ones(1)

    # -- conveniences --------------------------------------------------------------------
    @classmethod
    def example(cls) -> FrictionModel | None:
        """A typical instance (used by `stickslip models`, the docs and the contract tests
        that every registered model must pass); None if the model offers none."""
        return None

    @classmethod
    def parameters(cls) -> dict[str, Any]:
        """The parameters of the model: `{name: default}` (`dataclasses.MISSING` if
        required)."""
        import dataclasses

        return {
            f.name: (f.default if f.default is not dataclasses.MISSING else dataclasses.MISSING)
            for f in dataclasses.fields(cls)
        }

    @classmethod
    def params_model(cls):
        """The pydantic model that checks this model's `params` in a study: unknown names,
        missing required ones and wrong types. The default is built from `parameters()` and
        the field annotations; values are then checked by constructing the model."""
        from ._params_model import default_params_model

        return default_params_model(cls)

    @property
    def state_dim(self) -> int:
        return len(self.state_names)

    def params(self) -> dict[str, Any]:
        """The model's parameters as a plain dict (field name -> value)."""
        import dataclasses

        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}


class ChainModel(FrictionModel):
    """A chain of blocks with per-block stick and slip, simulated by `simulate_chain`.

    A concrete chain provides `n_blocks`, `k_c`, `k_p`, `v_b`, `D`, `tau` (None: white
    noise), `friction` (a `stickslip.friction.FrictionLaw`), `boundary` (`"free"` or
    `"periodic"`), `threshold` (None, or a law with `sample(key)` drawing a factor on the
    static limit at each stick) and `event_level` (the mean sliding velocity below which the
    chain counts as quiet, for the crossing statistics; 0 by default).
    """

    n_blocks: eqx.AbstractVar[int]
    k_c: eqx.AbstractVar[float]
    k_p: eqx.AbstractVar[float]
    v_b: eqx.AbstractVar[float]
    D: eqx.AbstractVar[float]
    tau: eqx.AbstractVar[float | None]
    friction: eqx.AbstractVar[Any]
    boundary: eqx.AbstractVar[str]
    threshold: eqx.AbstractVar[Any]
    event_level: eqx.AbstractVar[float]

    # The single-crossing view (the free chain, every block sliding): the state is
    # (u_1..u_N, V_1..V_N[, eta_1..eta_N]); the crossing variable is the mean sliding
    # velocity, negated so that "quiet" is an upcrossing.
    @property
    def state_names(self):
        n = self.n_blocks
        names = [f"u{i}" for i in range(n)] + [f"V{i}" for i in range(n)]
        return tuple(names + ([f"eta{i}" for i in range(n)] if self.tau is not None else []))

    @property
    def noise_dim(self):
        return self.n_blocks

    def _split(self, y):
        n = self.n_blocks
        return y[:n], y[n : 2 * n], (y[2 * n :] if self.tau is not None else None)

    def force(self, u, t=0.0):
        """Spring force on every block (coupling and loading) at time t."""
        if self.boundary == "periodic":
            lap = jnp.roll(u, 1, -1) + jnp.roll(u, -1, -1) - 2.0 * u
        else:
            pad = jnp.concatenate([u[..., :1], u, u[..., -1:]], axis=-1)
            lap = pad[..., 2:] + pad[..., :-2] - 2.0 * u
        return self.k_c * lap + self.k_p * (self.v_b * t - u)

    def drift(self, y):
        u, V, eta = self._split(y)
        a = self.force(u) - self.friction.force(V)
        if eta is None:
            return jnp.concatenate([V, a])
        return jnp.concatenate([V, a + eta, -eta / self.tau])

    def diffusion(self, y):
        n = self.n_blocks
        g = jnp.sqrt(2.0 * self.D) * jnp.eye(n)
        z = jnp.zeros((n, n))
        if self.tau is None:
            return jnp.concatenate([z, g])
        return jnp.concatenate([z, z, g / self.tau])

    @property
    def stick_level(self):
        return -self.event_level

    def crossing(self, y):
        return -jnp.mean(self._split(y)[1])

    def position(self, y):
        return jnp.mean(self._split(y)[0])

    @property
    def crossing_is_smooth(self):
        return self.tau is not None or self.D == 0.0

    def onset_state(self, key):
        """The relaxed chain: every block at rest where its loading spring is slack (the
        start of `simulate_chain`; an event starts when the first block releases)."""
        return jnp.zeros(len(self.state_names))


class CreepingSlider(FrictionModel):
    r"""A spring-driven slider whose friction has memory and whose velocity never reaches
    zero (rate-and-state friction): one motion through stick and slip.

    Its "stick" is a creep, many decades of velocity below the drive, with no closed form:
    `simulate` and `simulate_cycles` integrate the whole motion with an implicit adaptive
    solver (diffrax's `Kvaerno5`), so that the state runs on from one cycle into the next.
    Sticks and slips are read from the force, as `extract_cycles` reads a measured trace:
    **a slip is where the force falls** (the slider outruns the drive, $v > v_b$), from a
    force peak to the next trough, and **a stick is where it rises**, from that trough to
    the next peak. The cycles carry `peak_force` and `force_drop`, and `slip_distance` is
    the drop over the stiffness (the paper's $d$, as for force traces).

    A concrete model is a final class whose fields are its parameters (validated in
    `__check_init__`), among them `v_b` (the driving speed) and `stiffness`. It states, as
    any `FrictionModel`, `state_names`, `noise_dim`, and `drift` and `diffusion` of the
    whole motion (not of the slip alone), `onset_state(key)` (where a run starts), and
    besides:

    - `slider_velocity(y)` and `spring_force(y)` of one state;
    - `steady_state()`: the state of steady sliding at `v_b`, about which
      `linear_rates()` and `stability_report` linearise the motion.

    The integrator's tolerances apply to the state in the model's own variables: scale
    them to O(1) (the `rate-and-state` plugin holds the force in units of $N a$ and the
    velocity over $v_b$). Friction noise is the `diffusion` driven by white noise held
    constant over each interval of a grid of step `dt` (Wong-Zakai: the Stratonovich SDE as
    `dt` falls, the same as Ito's for additive noise)."""

    carries_state = True
    v_b: eqx.AbstractVar[float]
    stiffness: eqx.AbstractVar[float]

    @abc.abstractmethod
    def slider_velocity(self, y):
        """The slider's velocity in one state."""

    @abc.abstractmethod
    def spring_force(self, y):
        """The spring's force on the slider in one state."""

    @abc.abstractmethod
    def steady_state(self):
        """The state of steady sliding at the driving speed, shape `(d,)`."""

    # What the events watch: the force falls (a slip) where the slider outruns the drive.
    def crossing(self, y):
        return self.slider_velocity(y) / self.v_b - 1.0

    @property
    def stick_level(self):
        return 0.0

    @property
    def crossing_is_smooth(self) -> bool:
        return True

    def release(self, key, y_stick):
        raise NotImplementedError("a creeping slider is integrated through its sticks")

    def linear_rates(self) -> np.ndarray:
        """Eigenvalues (per unit time) of the noise-free motion linearised about
        `steady_state()`. A state component that no other drives and that does not grow
        (the friction noise, relaxing or held at zero) is an input, not a mode, and is left
        out. Steady sliding is linearly stable where every real part is negative."""
        J = np.asarray(jax.jacfwd(self.drift)(jnp.asarray(self.steady_state())))
        keep = [i for i in range(J.shape[0]) if np.any(np.delete(J[i], i) != 0.0) or J[i, i] > 0]
        return np.linalg.eigvals(J[np.ix_(keep, keep)])


def to_arrays(model: FrictionModel) -> FrictionModel:
    """Turn float parameters into float64 0-d arrays, so that jitted code takes them as
    inputs: a new parameter value then reuses the compiled code instead of recompiling.
    NumPy arrays (a JAX array each cost ~50 us to make, 1 ms a run for the Langevin model)."""

    def conv(x):
        if isinstance(x, float) or (isinstance(x, np.floating)):
            return np.asarray(x, dtype=np.float64)
        return x

    return jax.tree_util.tree_map(conv, model)


def time_scales(model: FrictionModel) -> tuple[float, float] | None:
    """`(fastest, slowest)` time scales of a linear-Gaussian slip, 1/max and 1/min of
    |eig(A)| over the nonzero rates (noise included); None without a linear-Gaussian slip.
    The grids of the estimator, the stability report and the method selection follow them."""
    lg = model.linear_gaussian()
    if lg is None:
        return None
    rates = np.abs(np.linalg.eigvals(np.asarray(lg.A, float)))
    rates = rates[rates > 0]
    if rates.size == 0:
        return 1.0, 1.0
    return 1.0 / float(rates.max()), 1.0 / float(rates.min())
