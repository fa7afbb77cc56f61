"""Import point for JAX inside the package: float64 everywhere, and a persistent cache of
compiled code.

Every module that uses JAX imports it from here, so `jax_enable_x64` is set before the first
array is made. `import stickslip` alone does not import this module (it stays light).

Compiling the simulator's loop takes about a second per buffer size on a 2-core CPU, so
compiled code is kept on disk between runs (JAX's persistent compilation cache) in
`$STICKSLIP_CACHE_DIR`, default `~/.cache/stickslip/jax`; set `STICKSLIP_CACHE_DIR=off` to
disable it. A cache directory the user configured for JAX is left alone.
"""

import os

from . import _cache, _cpu

# XLA's CPU runtime can deadlock on these workloads (seen here on 2 cores; a known issue,
# e.g. PyAutoFit #1528): a call waits forever with every worker idle.
# - Multithreaded Eigen on vmapped small matrix products: single-threaded Eigen avoids it
#   (the simulator's hot loop has no matrix products, so it costs nothing there).
# - The concurrency-optimised thunk scheduler: the estimator's vmapped n1(x, t) kernel hung
#   within 30 repeated calls in each of 3 runs with it on, and completed 3 x 60 calls with it
#   off (`--xla_cpu_enable_concurrency_optimized_scheduler=false`).
# Speed: on a CPU with AVX-512, XLA still emits 256-bit vectors unless told otherwise; 512
# made the exact refinement 1.2x and a whole run 1.1x faster on the 2-core AMD EPYC (Zen 4) of
# DESIGN.md's measurements, with the same results to the last bit (elementwise code; checked
# on exact and Euler-Maruyama runs). `benchmarks/vector_width.py` measures it on a machine.
# Must be set before JAX starts its backend; a value the user set for any of them is kept.
_FLAGS = {
    "xla_cpu_multi_thread_eigen": "false",
    "xla_cpu_enable_concurrency_optimized_scheduler": "false",
}
if _cpu.has_avx512():
    _FLAGS["xla_cpu_prefer_vector_width"] = "512"
for _flag, _value in _FLAGS.items():
    if _flag not in os.environ.get("XLA_FLAGS", ""):
        os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") + f" --{_flag}={_value}").strip()

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)


def _enable_compilation_cache() -> None:
    if jax.config.jax_compilation_cache_dir:
        return
    where = _cache.own_directory()
    if where is None:
        return
    why = _cache.prepare(where, tighten="STICKSLIP_CACHE_DIR" not in os.environ)
    if why is not None:  # run without the cache (say why where it cannot be trusted)
        if "cannot be made" not in why:
            import warnings

            warnings.warn(
                f"stickslip: the compiled-code cache {where} is not used: {why} (set "
                "STICKSLIP_CACHE_DIR to a folder of your own)",
                RuntimeWarning,
                stacklevel=2,
            )
        return
    jax.config.update("jax_compilation_cache_dir", str(where))
    # Only the costly compilations (the simulator's loops) are worth a disk entry.
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.2)
    _key_by_cpu()
    global CACHE_SET_HERE
    CACHE_SET_HERE = True


CACHE_SET_HERE = False  # whether this module set JAX's cache directory (and its CPU key)


def _key_by_cpu() -> None:
    """Add the CPU kind to the keys of JAX's persistent cache, whose CPU entries are
    otherwise keyed by `platform_version` "cpu" alone: one cache directory shared by the
    nodes of a cluster then holds one executable per CPU kind instead of handing a node code
    compiled for another. (A hook JAX keeps for this, `jax._src.cache_key.custom_hook`;
    without it, as in another JAX version, the cache is left as it is.)"""
    try:
        from jax._src import cache_key
    except ImportError:  # pragma: no cover - another JAX
        return
    before = getattr(cache_key, "custom_hook", None)
    if not callable(before) or getattr(before, "_stickslip", False):
        return

    def custom_hook() -> str:
        return before() + f"stickslip-cpu:{_cpu.KIND}"

    custom_hook._stickslip = True
    cache_key.custom_hook = custom_hook


_enable_compilation_cache()

import jax.numpy as jnp  # noqa: E402


def materialised(fn, pred):
    """`fn()` (arrays) computed in a conditional branch of its own, taken where `pred` holds
    (a traced value that is true wherever the result matters; the other branch gives zeros).
    XLA on a CPU re-derives a value inside each fused consumer (an optimization barrier does
    not stop it): twice the work and twice the code to compile for a value read twice. A
    branch's result is materialised once. (On an accelerator a branch in a loop waits for
    the host: the callers use it on a CPU, or outside a loop's every step.)"""
    shapes = jax.eval_shape(fn)
    nothing = lambda: jax.tree.map(lambda x: jnp.zeros(x.shape, x.dtype), shapes)  # noqa: E731
    return jax.lax.cond(pred, fn, nothing)


__all__ = ["jax", "jnp", "materialised"]
