"""Ahead-of-time compilation with a process-wide cache, so compile time is measured apart
from run time (benchmarks report them separately) and paid once per shape."""

from __future__ import annotations

import time

import equinox as eqx

from ._jax import jax

_cache: dict = {}


class Timer:
    """Accumulates the seconds spent compiling during one run."""

    def __init__(self):
        self.compile_seconds = 0.0


def call(fn, *args, timer: Timer | None = None):
    """Call `fn` (an `eqx.filter_jit` function) through a compiled executable cached by the
    structure, shapes and dtypes of the array arguments and the value of the others."""
    dynamic, static = eqx.partition(args, eqx.is_array)
    leaves, treedef = jax.tree_util.tree_flatten(dynamic)
    key = (fn, treedef, tuple((x.shape, str(x.dtype)) for x in leaves), static)
    compiled = _cache.get(key)
    if compiled is None:
        start = time.perf_counter()
        compiled = fn.lower(*args).compile()
        if timer is not None:
            timer.compile_seconds += time.perf_counter() - start
        _cache[key] = compiled
    return compiled(*args)
