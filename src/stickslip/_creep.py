r"""Sliders that creep instead of stopping: friction with memory (rate-and-state and its
kin) as one ODE, or SDE with friction noise, through stick and slip.

A `CreepingSlider` is a spring-driven slider whose velocity never reaches zero: its "stick"
is a creep, many decades of velocity below the driving speed, and its state (a contact age,
the slider's velocity, the spring's stretch) runs on from one cycle into the next. There is
no closed-form stick: the whole motion is integrated, adaptively and implicitly (the creep
is stiff: the velocity relaxes in $M v / (N a)$, 1e-8 s at 1 nm/s for a 30 g slider), and
sticks and slips are read off it with the definition `extract_cycles` applies to a force
trace: **a slip is where the force falls** (the slider outruns the drive, $v > v_b$), from
a force peak to the next trough; **a stick is where the force rises**, from that trough to
the next peak. So `peak_force`, `force_drop`, `slip_time`, `stick_time` and `period` are
those of a measured trace's cycles, and `slip_distance` is the drop over the stiffness
(the paper's $d$, as for force traces).

Friction noise enters through the model's `diffusion` driven by white noise held constant
over each interval of a grid of step `dt` (Wong-Zakai): as `dt` falls this converges to the
Stratonovich SDE, the same as Ito's for the additive noise of an Ornstein-Uhlenbeck friction
force. The grid's draws are keyed by `(seed, path, interval)`, so a path's noise does not
depend on how its solves are cut.
"""

from __future__ import annotations

import abc
import dataclasses
import math
import time
import warnings
from typing import Any

import diffrax
import equinox as eqx
import numpy as np
import optimistix as optx

from . import _rng
from ._errors import ParameterError, check_choice, check_int, check_positive
from ._jax import jax, jnp
from ._model import FrictionModel

# Streams of the noise grid (beside the hybrid simulator's, `_rng`).
_NOISE_STREAM = 8
# Relative and absolute tolerances of the implicit integration, of the state in the model's
# own variables (a plugin scales them to O(1)); the PID coefficients of stiff problems
# (Hairer and Wanner; fewer rejected steps than the integral controller here: 63 k steps
# with 23 k rejected against 68 k with 37 k, on 15 s of the paper-like slider at 1e-9).
RTOL, ATOL = 1e-8, 1e-8
_PID = dict(pcoeff=0.3, icoeff=0.4)
_MAX_STEPS = 200_000  # steps of one solve (a stick or a slip)
# A limit cycle whose slowest velocity stays above this fraction of the drive is an
# oscillation; below it the slider (nearly) stops, and the force rises along the loading
# line at k v_b to within this fraction: a stick-slip, as a force trace shows it.
STICK_FRACTION = 0.1


class CreepingSlider(FrictionModel):
    r"""A spring-driven slider with friction that has memory: one continuous motion.

    A concrete model is a final class whose fields are its parameters (validated in
    `__check_init__`). It states, as any `FrictionModel`, the state (`state_names`), the
    `drift` and `diffusion` of the whole motion (not of the slip alone), `noise_dim` and
    `onset_state(key)` (where a run starts); and besides:

    - `v_b`, `stiffness`: the driving speed and the spring's stiffness (fields);
    - `slider_velocity(y)` and `spring_force(y)` of one state;
    - `steady_state()`: the state of steady sliding at `v_b` (for the linear stability of
      `stability_report` and the regime).

    `simulate` and `simulate_cycles` integrate it with an implicit adaptive solver
    (diffrax's `Kvaerno5`) and find the force's peaks and troughs as events; the state
    runs on from cycle to cycle (`carries_state`). The crossing variable of the hybrid
    models has no part here: `crossing` is $v/v_b - 1$, positive in a slip."""

    carries_state = True

    @abc.abstractmethod
    def slider_velocity(self, y):
        """The slider's velocity (> 0) in one state."""

    @abc.abstractmethod
    def spring_force(self, y):
        """The spring's force on the slider in one state."""

    @abc.abstractmethod
    def steady_state(self):
        """The state of steady sliding at the driving speed, shape `(d,)`."""

    # The hybrid simulator's methods, as the motion sees them: the force falls (a slip)
    # where the slider outruns the drive.
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


# -- integration ---------------------------------------------------------------------------


def _noise(key, t, h, m):
    """The white noise held over the grid interval of `t` (step `h`): `m` normals / sqrt(h)."""
    j = jnp.floor(t / h).astype(jnp.int64)
    high, low = (j >> 31).astype(jnp.uint32), j.astype(jnp.uint32)
    k = jax.random.fold_in(jax.random.fold_in(key, high), low)
    return jax.random.normal(k, (m,), dtype=jnp.float64) / jnp.sqrt(h)


def _vector_field(model, noisy: bool):
    def vf(t, y, args):
        key, h = args
        f = model.drift(y)
        if noisy:
            f = f + model.diffusion(y) @ _noise(key, t, h, model.noise_dim)
        return f

    return vf


@eqx.filter_jit
def _segment(model, noisy: bool, y0, t0, sign, key, h, t_end, rtol, atol):
    """Integrate each path from `t0` until `sign * crossing` rises through zero (a slip's end
    with sign -1, a stick's end with +1) or until `t_end`. Returns the end time and state,
    whether the event ended it, and the slider's least velocity on the way (at the steps)."""

    def one(y0, t0, sign, key):
        term = diffrax.ODETerm(_vector_field(model, noisy))

        def cond(t, y, args, **kwargs):
            return sign * model.crossing(y)

        event = diffrax.Event(
            cond,
            root_finder=optx.Bisection(rtol=1e-10, atol=1e-12, expand_if_necessary=True),
            direction=True,
        )
        dtmax = h if noisy else None
        controller = diffrax.PIDController(rtol=rtol, atol=atol, dtmax=dtmax, **_PID)
        sol = diffrax.diffeqsolve(
            term, diffrax.Kvaerno5(), t0, t_end, None, y0, args=(key, h),
            stepsize_controller=controller, event=event, saveat=diffrax.SaveAt(t1=True),
            max_steps=_MAX_STEPS, throw=False,
        )  # fmt: skip
        # An event whose root the bisection placed within its time tolerance but reported
        # as unconverged (the force's trough is steep: the slider stops in M v / (N a))
        # still ends the segment where the crossing vanishes; it is an event all the same.
        y1 = sol.ys[-1]
        hit = jnp.asarray(sol.event_mask) & (jnp.abs(model.crossing(y1)) < 1e-6)
        ok = (sol.result == diffrax.RESULTS.successful) | hit
        ok = ok | (sol.result == diffrax.RESULTS.event_occurred)
        return sol.ts[-1], y1, hit, ok, sol.stats["num_steps"]

    return jax.vmap(one)(y0, t0, sign, key)


@dataclasses.dataclass
class _Paths:
    """The host-side state of a run's paths: where each is, in which phase."""

    y: np.ndarray  # (n, d)
    t: np.ndarray  # (n,)
    slipping: np.ndarray  # (n,) bool
    alive: np.ndarray  # (n,) bool


def _keys(seed: int, paths: np.ndarray):
    root = _rng.stream_key(_rng.seed_key(seed), _NOISE_STREAM)
    return jax.vmap(lambda p: jax.random.fold_in(jnp.asarray(root), p))(jnp.asarray(paths))


def _check_noise_step(owner: str, model: CreepingSlider, dt: float, noisy: bool) -> None:
    tau = getattr(model, "tau", None)
    if noisy and tau is not None and dt > 0.5 * float(tau):
        raise ParameterError(
            owner, "dt",
            f"is the noise's grid step: at most tau / 2 = {0.5 * float(tau):.3g} "
            "(the friction noise's correlation time) so that the noise is resolved",
            dt,
        )  # fmt: skip


class _Integrator:
    """One configured run of a creeping slider: segments (a slip or a stick) of many paths."""

    def __init__(self, owner, model, dt, t_max, seed, rtol, atol):
        from ._model import _to_arrays

        self.model = _to_arrays(model)
        self.noisy = bool(np.any(np.asarray(model.diffusion(model.steady_state())) != 0.0))
        _check_noise_step(owner, model, dt, self.noisy)
        self.dt, self.t_max, self.seed = dt, t_max, seed
        self.rtol, self.atol = rtol, atol
        self.stats = {"segments": 0, "steps": 0, "failed": 0}

    def advance(self, keys, p: _Paths, idx):
        """One segment for the paths `idx`: each ends its slip or its stick."""
        sign = np.where(p.slipping[idx], -1.0, 1.0)
        t1, y1, hit, ok, steps = _segment(
            self.model, self.noisy, jnp.asarray(p.y[idx]), jnp.asarray(p.t[idx]),
            jnp.asarray(sign), keys[idx], jnp.asarray(self.dt), jnp.asarray(self.t_max),
            self.rtol, self.atol,
        )  # fmt: skip
        self.stats["segments"] += 1
        self.stats["steps"] += int(np.sum(np.asarray(steps)))
        self.stats["failed"] += int(np.sum(~np.asarray(ok)))
        return np.asarray(t1), np.asarray(y1), np.asarray(hit)


def _forces(model, ys):
    return np.asarray(jax.vmap(model.spring_force)(jnp.asarray(ys)))


def run_cycles(owner, model, n_paths, dt, t_max, seed, max_cycles, first_only=False):
    """Successive cycles of `n_paths` paths to `t_max` (or the first slip and the stick after
    it of each, `first_only`). Returns the table (dict of arrays, one row per cycle), the
    onset and end states, and the run's stats."""
    integ = _Integrator(owner, model, dt, t_max, seed, RTOL, ATOL)
    m = integ.model
    path_ids = np.arange(n_paths, dtype=np.uint32)
    keys = _keys(seed, path_ids)
    y0 = np.asarray(jax.vmap(m.onset_state)(jax.random.split(jax.random.key(seed), n_paths)))
    c0 = np.asarray(jax.vmap(m.crossing)(jnp.asarray(y0)))
    p = _Paths(y=y0.copy(), t=np.zeros(n_paths), slipping=c0 > 0.0, alive=np.ones(n_paths, bool))
    rows: list[dict[str, np.ndarray]] = []
    # The cycle in the making of each path: where its slip started (time, state, force).
    start_t = np.where(p.slipping, 0.0, np.nan)
    start_y = np.where(p.slipping[:, None], y0, np.nan)
    end_t = np.full(n_paths, np.nan)  # its slip's end
    end_y = np.full_like(y0, np.nan)
    count = np.zeros(n_paths, dtype=np.int64)
    while p.alive.any():
        idx = np.nonzero(p.alive)[0]
        t1, y1, hit = integ.advance(keys, p, idx)
        was_slip = p.slipping[idx]
        # A slip ends: remember where; a stick ends: the cycle (slip + stick) is complete.
        s, k = idx[was_slip & hit], idx[~was_slip & hit]
        end_t[s], end_y[s] = t1[was_slip & hit], y1[was_slip & hit]
        done = k[np.isfinite(start_t[k])]
        if done.size:
            sel = np.isin(idx, done)
            rows.append(_rows(m, done, start_t[done], start_y[done], end_t[done], end_y[done],
                              t1[sel], y1[sel], count[done]))  # fmt: skip
            count[done] += 1
        start_t[k], start_y[k] = t1[~was_slip & hit], y1[~was_slip & hit]
        p.t[idx], p.y[idx] = t1, y1
        p.slipping[idx] = np.where(hit, ~was_slip, was_slip)
        p.alive[idx] = hit & (t1 < t_max) & (count[idx] < max_cycles)
        if first_only:
            p.alive[idx] &= count[idx] == 0
    # A slip that ended but whose stick outlasted t_max: a row without a stick time.
    open_ = np.isfinite(start_t) & np.isfinite(end_t) & (end_t > start_t) & (count < max_cycles)
    open_ &= ~(first_only & (count > 0))
    if np.any(open_):
        o = np.nonzero(open_)[0]
        none = np.full(o.size, np.nan), np.full_like(end_y[o], np.nan)
        rows.append(_rows(m, o, start_t[o], start_y[o], end_t[o], end_y[o], *none, count[o]))
    if not rows:
        table = {k: np.zeros(0) for k in _COLUMNS}
        table.update(path=np.zeros(0, np.int64), cycle=np.zeros(0, np.int64))
        table["onset"] = np.zeros((0, y0.shape[1]))
        table["stick"] = np.zeros((0, y0.shape[1]))
        table["next"] = np.zeros((0, y0.shape[1]))
    else:
        table = {k: np.concatenate([r[k] for r in rows]) for k in rows[0]}
    order = np.lexsort((table["cycle"], table["path"]))
    table = {k: v[order] for k, v in table.items()}
    if integ.stats["failed"]:
        warnings.warn(
            f"{owner}: {integ.stats['failed']} solve(s) of the creeping slider stopped short "
            f"(more than {_MAX_STEPS} steps or a failed implicit step); their paths end there",
            stacklevel=3,
        )
    return table, y0, integ.stats


_COLUMNS = (
    "release_time", "slip_time", "stick_position", "slip_distance", "stick_time", "period",
    "peak_force", "force_drop",
)  # fmt: skip


def _rows(m, paths, t0, y0, t1, y1, t2, y2, cycle):
    F0, F1 = _forces(m, y0), _forces(m, y1)
    k = float(np.asarray(m.stiffness))
    pos = np.asarray(jax.vmap(m.position)(jnp.asarray(y1)))
    slip_time = t1 - t0
    stick_time = t2 - t1
    return dict(
        path=paths.astype(np.int64), cycle=cycle.copy(), release_time=t0, slip_time=slip_time,
        stick_position=pos, slip_distance=(F0 - F1) / k, stick_time=stick_time,
        period=slip_time + stick_time, peak_force=F0, force_drop=F0 - F1,
        onset=y0, stick=y1, next=y2,
    )  # fmt: skip


def simulate(model, n_paths, dt, t_max, seed, owner="simulate"):
    """`stickslip.simulate` of a creeping slider: each path's first slip (from its onset
    state, or from the first force peak after it) and the stick after it."""
    from ._simulate.ensemble import Ensemble

    wall0 = time.perf_counter()
    table, y0, stats = run_cycles(owner, model, n_paths, dt, t_max, seed, 1, first_only=True)
    d = y0.shape[1]
    out = {k: np.full(n_paths, np.nan) for k in _COLUMNS}
    onset = np.full((n_paths, d), np.nan)
    stick = np.full((n_paths, d), np.nan)
    nxt = np.full((n_paths, d), np.nan)
    first = table["cycle"] == 0
    rows = table["path"][first]
    for k in _COLUMNS:
        out[k][rows] = table[k][first]
    onset[rows], stick[rows], nxt[rows] = (table[k][first] for k in ("onset", "stick", "next"))
    stuck = np.isfinite(out["slip_time"]) & (out["release_time"] + out["slip_time"] <= t_max)
    info = dict(model=type(model).__name__, params=model.params(), solver="kvaerno5",
                monitor="events", dt=dt, t_max=t_max, seed=seed, rtol=RTOL, atol=ATOL)  # fmt: skip
    stats = dict(stats, wall_seconds=time.perf_counter() - wall0)
    return Ensemble(
        slip_time=out["slip_time"], stick_position=out["stick_position"],
        slip_distance=out["slip_distance"], stick_time=out["stick_time"],
        period=out["period"], immediate=np.zeros(n_paths, bool), stuck=stuck,
        onset_state=onset, stick_state=stick, next_onset_state=nxt,
        state_names=tuple(model.state_names), info=info, stats=stats,
    )  # fmt: skip


def simulate_cycles(model, n_paths, dt, t_max, seed, record, max_cycles):
    """`stickslip.simulate_cycles` of a creeping slider."""
    from ._simulate.cycles import CycleSeries

    wall0 = time.perf_counter()
    table, y0, stats = run_cycles("simulate_cycles", model, n_paths, dt, t_max, seed, max_cycles)
    cycles = {k: table[k] for k in ("path", "cycle", *_COLUMNS)}
    cycles["immediate"] = np.zeros(cycles["path"].size, bool)
    traces = _traces(model, n_paths, dt, t_max, seed, y0) if record else None
    info = dict(model=type(model).__name__, params=model.params(), solver="kvaerno5",
                monitor="events", dt=dt, t_max=t_max, seed=seed, n_paths=n_paths,
                rtol=RTOL, atol=ATOL)  # fmt: skip
    stats = dict(stats, wall_seconds=time.perf_counter() - wall0)
    return CycleSeries(cycles, traces, tuple(model.state_names), info, stats)


_RECORD_SAMPLES = 20_000  # samples of a recorded trajectory at most (evenly spaced)


@eqx.filter_jit
def _dense(model, noisy: bool, y0, key, h, ts, rtol, atol):
    def one(y0, key):
        dtmax = h if noisy else None
        sol = diffrax.diffeqsolve(
            diffrax.ODETerm(_vector_field(model, noisy)), diffrax.Kvaerno5(), ts[0], ts[-1],
            None, y0, args=(key, h), saveat=diffrax.SaveAt(ts=ts),
            stepsize_controller=diffrax.PIDController(rtol=rtol, atol=atol, dtmax=dtmax, **_PID),
            max_steps=16 * _MAX_STEPS, throw=False,
        )  # fmt: skip
        return sol.ys

    return jax.vmap(one)(y0, key)


def _traces(model, n_paths, dt, t_max, seed, y0):
    """The time series of every path on an even grid (at most `_RECORD_SAMPLES` samples; the
    same noise as the cycles: one solve through, so within the tolerances of the events')."""
    integ = _Integrator("simulate_cycles", model, dt, t_max, seed, RTOL, ATOL)
    n = int(min(_RECORD_SAMPLES, max(2, math.ceil(t_max / dt) + 1)))
    ts = np.linspace(0.0, t_max, n)
    keys = _keys(seed, np.arange(n_paths, dtype=np.uint32))
    ys = np.asarray(
        _dense(
            integ.model,
            integ.noisy,
            jnp.asarray(y0),
            keys,
            jnp.asarray(dt),
            jnp.asarray(ts),
            RTOL,
            ATOL,
        )  # fmt: skip
    )
    out = []
    for p in range(n_paths):
        slipping = np.asarray(jax.vmap(integ.model.crossing)(jnp.asarray(ys[p]))) > 0.0
        out.append((ts.copy(), ys[p], slipping))
    return tuple(out)


# -- regime ----------------------------------------------------------------------------------


@dataclasses.dataclass(frozen=True)
class SlidingRegime:
    """What a creeping slider does at its parameters (from `stability_report`).

    - `regime`: `"steady sliding"` (steady sliding at `v_b` is linearly stable),
      `"oscillation"` (it is unstable and the noise-free motion settles on a limit cycle
      whose slider never slows below `STICK_FRACTION` of `v_b`) or `"stick-slip"` (it does);
    - `evidence`: one line with the numbers that decided it;
    - `eigenvalues`: of the linearised motion about steady sliding (the noise's own decay
      left out), per second;
    - `min_velocity_ratio`, `period`, `force_drop`: of the noise-free limit cycle (nan when
      steady sliding is stable).
    """

    model: str
    regime: str
    evidence: str
    eigenvalues: np.ndarray
    min_velocity_ratio: float
    period: float
    force_drop: float

    def __str__(self) -> str:
        return f"SlidingRegime: {self.model}: {self.regime} ({self.evidence})"


def linear_rates(model: CreepingSlider) -> np.ndarray:
    """Eigenvalues of the linearised noise-free motion about steady sliding (per second),
    the modes the noise alone drives (zero rows of the Jacobian's coupling) left out."""
    y = jnp.asarray(model.steady_state())
    J = np.asarray(jax.jacfwd(model.drift)(y))
    # A state component that no other one drives and that does not grow (the friction
    # noise, relaxing or held at zero) is an input to the slider, not one of its modes.
    keep = [i for i in range(J.shape[0]) if np.any(np.delete(J[i], i) != 0.0) or J[i, i] > 0]
    return np.linalg.eigvals(J[np.ix_(keep, keep)])


def regime(model: CreepingSlider, *, cycles: int = 40, dt: float | None = None) -> SlidingRegime:
    """The regime of a creeping slider: linear stability of steady sliding, then, where it
    is unstable, the noise-free limit cycle (the last of `cycles` cycles from the model's
    onset; `dt`: the largest step, default a hundredth of the linear period)."""
    owner = "stability_report"
    cycles = check_int(owner, "cycles", cycles, minimum=4)
    rates = linear_rates(model)
    name = type(model).__name__
    growth = float(np.max(rates.real))
    if growth < 0:
        return SlidingRegime(
            name, "steady sliding",
            f"steady sliding at v_b is linearly stable (slowest decay {growth:.3g} /s)",
            rates, math.nan, math.nan, math.nan,
        )  # fmt: skip
    quiet = eqx.tree_at(lambda m: m.D, model, 0.0) if hasattr(model, "D") else model
    omega = float(np.max(np.abs(rates.imag))) or abs(growth)
    if dt is None:
        dt = 2 * math.pi / omega / 100.0
    dt = check_positive(owner, "dt", dt)
    # Long enough for the perturbation to grow from the onset and for `cycles` cycles.
    t_max = (cycles + 4) * 2 * math.pi / omega + 40.0 / growth
    table, _, _ = run_cycles(owner, quiet, 1, dt, t_max, 0, cycles)
    done = np.isfinite(table["period"])
    if done.sum() < 3:
        return SlidingRegime(
            name, "steady sliding",
            f"steady sliding is linearly unstable (growth {growth:.3g} /s) but the noise-free "
            f"motion made {int(done.sum())} cycle(s) in {t_max:.3g} s",
            rates, math.nan, math.nan, math.nan,
        )  # fmt: skip
    last = np.nonzero(done)[0][-1]
    y_trough = table["stick"][last]
    # The least velocity of the last cycle's stick: densely, along its solve.
    vmin = _least_velocity(quiet, y_trough, table["stick_time"][last], dt)
    ratio = vmin / float(model.v_b)
    kind = "stick-slip" if ratio < STICK_FRACTION else "oscillation"
    drop = float(table["force_drop"][last])
    period = float(table["period"][last])
    return SlidingRegime(
        name, kind,
        f"steady sliding unstable (growth {growth:.3g} /s); noise-free limit cycle: period "
        f"{period:.4g} s, force drop {drop:.4g}, least slider velocity {ratio:.3g} v_b "
        f"({'below' if ratio < STICK_FRACTION else 'above'} {STICK_FRACTION} v_b)",
        rates, ratio, period, drop,
    )  # fmt: skip


def _least_velocity(model, y0, T, dt):
    from ._model import _to_arrays

    m = _to_arrays(model)
    ts = np.linspace(0.0, float(T), 2001)
    key = _keys(0, np.zeros(1, np.uint32))
    ys = np.asarray(_dense(m, False, jnp.asarray(y0)[None], key, jnp.asarray(dt),
                           jnp.asarray(ts), RTOL, ATOL))[0]  # fmt: skip
    return float(np.min(np.asarray(jax.vmap(m.slider_velocity)(jnp.asarray(ys)))))


def check_args(owner, n_paths, dt, t_max, seed, solver, monitor) -> tuple:
    """The arguments of `simulate`/`simulate_cycles` that a creeping slider uses."""
    n_paths = check_int(owner, "n_paths", n_paths, minimum=1)
    dt = check_positive(owner, "dt", dt)
    t_max = check_positive(owner, "t_max", t_max)
    seed = check_int(owner, "seed", seed, minimum=0)
    check_choice(owner, "solver", solver, ("auto",))
    check_choice(owner, "monitor", monitor, ("continuous",))
    return n_paths, dt, t_max, seed


__all__: list[Any] = ["CreepingSlider", "SlidingRegime"]
