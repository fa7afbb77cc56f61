"""Checks of a model's own code, before and after it is simulated: the shapes its methods
return (probed once per model structure, without running anything), and the paths whose
state left the finite numbers (found by the simulator, explained here).

A model is user code: a drift of the wrong shape reached the user as JAX's own errors (`jvp
called with different primal and tangent shapes`), and a drift that is `nan` in part of the
state space quietly changed the fraction of paths that stick. Nothing here is traced into
the simulator's programs.
"""

from __future__ import annotations

import numpy as np

from ._errors import ParameterError

_checked: set = set()  # the model structures whose shapes were probed


def structure_key(model):
    """What the shapes of `model`'s methods may depend on: its class, its structure, the
    shapes of its arrays and the values of its other fields (an integer may set a shape),
    but not the value of a float (a fit's every point is a new one: probed again, 15 ms a
    point)."""
    from ._jax import jax

    leaves, treedef = jax.tree_util.tree_flatten(model)
    values = tuple(
        (np.shape(x), str(np.result_type(x))) if hasattr(x, "shape")
        else float if type(x) is float else repr(x)
        for x in leaves
    )  # fmt: skip
    return (type(model), str(treedef), values, tuple(model.state_names), model.noise_dim)


def check_shapes(owner: str, model) -> None:
    """Probe `model`'s methods once per structure (`jax.eval_shape`: traced, not compiled
    or run): `onset_state` gives a state of shape `(d,)` (`d` the state's names), `drift`
    `(d,)`, `diffusion` `(d, noise_dim)`, `crossing`, `crossing_rate` and `crossing_noise`
    a number, `stick_level` a finite number; `noise_dim` is an integer >= 1. A
    `ParameterError` names the method, the shape expected and the one returned."""
    try:
        key = structure_key(model)
    except Exception as err:  # state_names or noise_dim themselves fail
        raise ParameterError(owner, "model", f"{type(model).__name__}: {_short(err)}") from None
    if key in _checked:
        return
    from ._jax import jax, jnp

    name = type(model).__name__
    names = tuple(model.state_names)
    d = len(names)
    noise_dim = model.noise_dim
    if isinstance(noise_dim, bool) or not isinstance(noise_dim, int | np.integer):
        raise ParameterError(owner, "model", f"{name}.noise_dim must be an integer", noise_dim)
    if noise_dim < 1:
        raise ParameterError(
            owner, "model", f"{name}.noise_dim must be >= 1 (a Brownian motion at least; "
            "a noise-free model has a diffusion of zeros)", noise_dim,
        )  # fmt: skip
    state = f"a state of shape ({d},) ({', '.join(names)})"
    _probe(owner, name, "onset_state", model.onset_state, (jax.random.key(0),), (d,),
           "a key", f" (the state: {', '.join(names)})")  # fmt: skip
    y = jax.ShapeDtypeStruct((d,), jnp.float64)
    _probe(owner, name, "drift", model.drift, (y,), (d,), state)
    _probe(owner, name, "diffusion", model.diffusion, (y,), (d, int(noise_dim)), state,
           " (state, noise_dim)")  # fmt: skip
    for method in ("crossing", "crossing_rate", "crossing_noise"):
        _probe(owner, name, method, getattr(model, method), (y,), (), state)
    try:
        level = np.asarray(model.stick_level, dtype=float)
    except Exception as err:
        raise ParameterError(owner, "model", f"{name}.stick_level: {_short(err)}") from None
    if level.shape != ():
        raise ParameterError(
            owner, "model", f"{name}.stick_level has shape {level.shape}: expected a number"
        )
    if not np.isfinite(level):
        raise ParameterError(owner, "model", f"{name}.stick_level is {level}: a slip never ends")
    _checked.add(key)


def _probe(owner, name, method, fn, args, expected, what, meaning=""):
    from ._jax import jax

    try:
        out = jax.eval_shape(fn, *args)
    except Exception as err:
        try:  # (a method the simulator calls on concrete values: `onset_state`, eagerly)
            if any(isinstance(a, jax.ShapeDtypeStruct) for a in args):
                raise
            out = fn(*args)
        except Exception:
            raise ParameterError(
                owner, "model", f"{name}.{method} fails on {what}: {_short(err)}"
            ) from None
    shape = getattr(out, "shape", None)
    if shape is None or tuple(shape) != expected:
        got = "no array" if shape is None else f"shape {tuple(shape)}"
        raise ParameterError(
            owner, "model",
            f"{name}.{method} returns {got} for {what}: expected shape {expected}{meaning}",
        )  # fmt: skip


def _short(err: BaseException) -> str:
    text = str(err).strip().splitlines()
    return f"{type(err).__name__}: {text[0] if text else ''}".rstrip(": ")[:200]


def _state_text(names, y) -> str:
    return ", ".join(f"{n}={float(v):.4g}" for n, v in zip(names, y, strict=True))


_METHODS = ("drift", "diffusion", "crossing")


def _method_at(model, y):
    """`(method, "nan" or "inf", y)` for the first slip-phase method not finite at the
    state `y`, else `None`."""
    from ._jax import jnp

    for method in _METHODS:
        try:
            value = np.asarray(getattr(model, method)(jnp.asarray(y)), dtype=float)
        except Exception:  # (shapes were checked: a failure here says nothing more)
            continue
        if not np.all(np.isfinite(value)):
            return method, "nan" if np.any(np.isnan(value)) else "inf", np.asarray(y)
    return None


REPLAYS = 256  # Euler-Maruyama paths run from the onset to find where a model fails


def _replay(model, y0, dt: float, steps: int):
    """Where the model's own methods stop being finite along `REPLAYS` Euler-Maruyama paths
    from `y0` (noise of their own, not the run's: the run's paths went there, these likely
    do too), as `_method_at`; `None` if none does within `steps` steps. Only after a run
    found non-finite paths: one small compilation."""
    from ._jax import jax, jnp

    d, m = np.size(y0), int(model.noise_dim)
    steps = int(min(steps, 100_000))

    def flags(y):
        return jnp.stack([~jnp.all(jnp.isfinite(getattr(model, f)(y))) for f in _METHODS])

    def step(y, dw):
        bad = jax.vmap(flags, in_axes=1)(y)  # (paths, methods)
        f = jax.vmap(model.drift, in_axes=1, out_axes=1)(y)
        g = jax.vmap(model.diffusion, in_axes=1, out_axes=2)(y)  # (d, m, paths)
        return y + f * dt + jnp.einsum("dmp,mp->dp", g, dw), (y, bad)

    @jax.jit
    def run(y0, dws):
        _, (ys, bad) = jax.lax.scan(step, y0, dws)
        return ys, bad

    key = jax.random.key(0)
    dws = jax.random.normal(key, (steps, m, REPLAYS)) * np.sqrt(dt)
    start = jnp.broadcast_to(jnp.asarray(y0, dtype=float)[:, None], (d, REPLAYS))
    try:
        ys, bad = (np.asarray(a) for a in run(start, dws))
    except Exception:  # a model this cannot replay: say what is known
        return None
    hits = np.argwhere(bad)  # (step, path, method), in step order
    if not hits.size:
        return None
    t, path, method = hits[0]
    kind = _method_at(model, ys[t, :, path])
    return kind or (_METHODS[method], "nan", ys[t, :, path])


def explain(model, before, after, onset=None, dt=None, steps=0) -> str:
    """Where a path left the finite numbers: the first slip-phase method (drift,
    diffusion, crossing) that is not finite at the last finite state `before` known of it
    (else its `onset` state), else the stretch from there to the non-finite state `after`;
    `before` `None`: the onset state `after` itself was not finite."""
    names = tuple(model.state_names)
    name = type(model).__name__
    after = np.asarray(after, dtype=float)
    if before is None:
        return f"onset_state returns ({_state_text(names, after)})"
    if onset is not None and not np.all(np.isfinite(onset)):
        return f"onset_state returns ({_state_text(names, onset)})"
    before = np.asarray(before, dtype=float)
    if not np.all(np.isfinite(before)) and onset is not None:
        before = np.asarray(onset, dtype=float)
    if not np.all(np.isfinite(before)):
        return f"while slipping, before the state ({_state_text(names, after)})"
    found = _method_at(model, before)
    if found is None and dt is not None:
        found = _replay(model, before, dt, steps)
    if found is not None:
        method, kind, state = found
        return f"{name}.{method} returns {kind} at ({_state_text(names, state)})"
    bad = [n for n, v in zip(names, after, strict=True) if not np.isfinite(v)]
    return (f"while slipping from ({_state_text(names, before)}): {', '.join(bad)} became "
            "non-finite")  # fmt: skip


def warn_nonfinite(owner: str, model, count: int, n_paths: int, where: str, stacklevel=3):
    import warnings

    warnings.warn(
        f"{owner}: {count} of {n_paths} paths ({100 * count / n_paths:.3g} %) left the finite "
        f"numbers, {where}: they are not counted as stuck (Ensemble.nonfinite, "
        "stats['nonfinite']); check the model there",
        RuntimeWarning,
        stacklevel=stacklevel,
    )
