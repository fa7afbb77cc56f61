"""Counter-based random numbers."""

import numpy as np
import pytest
from jax.extend.random import threefry_2x32
from scipy import special, stats

from stickslip import _rng
from stickslip._jax import jax, jnp

# The draws as the simulator makes them, inside compiled code: one compilation per shape
# instead of one per primitive and shape (op by op), which cost 7 s of a cold test run.
normals = jax.jit(_rng.normals, static_argnums=3)
uniforms = jax.jit(_rng.uniforms, static_argnums=3)
tree_normals = jax.jit(_rng.tree_normals, static_argnums=4)
threefry2x32 = jax.jit(_rng.threefry2x32)
erfinv32 = jax.jit(_rng.erfinv32)


def test_unrolled_threefry_equals_jax():
    rng = np.random.default_rng(1)
    for _ in range(5):
        key = rng.integers(0, 2**32, size=2, dtype=np.uint32)
        x = rng.integers(0, 2**32, size=(2, 1000), dtype=np.uint32)
        ref = np.asarray(threefry_2x32(jnp.asarray(key), jnp.asarray(x)))
        w0, w1 = threefry2x32(jnp.asarray(key), jnp.asarray(x[0]), jnp.asarray(x[1]))
        np.testing.assert_array_equal(np.stack([w0, w1]), ref)


def test_draws_do_not_depend_on_the_batch():
    key = _rng.stream_key(_rng.seed_key(5), _rng.STEP)
    paths = np.arange(1000, dtype=np.uint32)
    full = np.asarray(normals(key, paths, 17, 3))
    some = np.asarray(normals(key, paths[[3, 999, 500]], 17, 3))
    np.testing.assert_array_equal(full[:, [3, 999, 500]], some)
    per_path_counter = np.asarray(normals(key, paths[:4], np.array([17, 17, 17, 17]), 3))
    np.testing.assert_array_equal(per_path_counter, full[:, :4])


def test_stream_keys_at_once_equal_jax_threefry():
    # The keys of a run, evaluated together in NumPy, against JAX's own Threefry on each.
    root = _rng.seed_key(2**40 + 7)
    pairs = [(_rng.STEP, 0), (_rng.LOCATE, 1), (_rng.TREE, 3)]
    for (stream, cycle), key in zip(pairs, _rng.stream_keys(root, pairs), strict=True):
        x = jnp.asarray(np.array([[stream], [cycle]], dtype=np.uint32))
        ref = np.asarray(threefry_2x32(jnp.asarray(root), x))[:, 0]
        assert key.dtype == np.uint32
        np.testing.assert_array_equal(key, ref)


def test_streams_seeds_and_counters_differ():
    paths = np.arange(64, dtype=np.uint32)
    root = _rng.seed_key(0)
    a = np.asarray(normals(_rng.stream_key(root, 1), paths, 0, 2))
    b = np.asarray(normals(_rng.stream_key(root, 2), paths, 0, 2))
    c = np.asarray(normals(_rng.stream_key(_rng.seed_key(1), 1), paths, 0, 2))
    d = np.asarray(normals(_rng.stream_key(root, 1), paths, 1, 2))
    for other in (b, c, d):
        assert not np.any(a == other)
    with pytest.raises(ValueError):
        _rng.seed_key(-1)


def test_normals_are_standard_normal():
    key = _rng.stream_key(_rng.seed_key(2), _rng.STEP)
    paths = np.arange(250_000, dtype=np.uint32)
    z = np.asarray(normals(key, paths, 3, 4)).ravel()
    n = z.size
    assert abs(z.mean()) < 4 / np.sqrt(n)
    assert abs(z.var() - 1) < 4 * np.sqrt(2 / n)
    assert stats.kstest(z, "norm").pvalue > 1e-3
    assert np.max(np.abs(z)) < 5.4  # float32 uniforms clip the tails near 5.3 sigma
    assert np.corrcoef(z[: n // 2], z[n // 2 :])[0, 1] < 4 / np.sqrt(n / 2)


def test_uniforms_are_open_unit():
    key = _rng.stream_key(_rng.seed_key(3), _rng.BRIDGE)
    u = np.asarray(uniforms(key, np.arange(100_000, dtype=np.uint32), 0, 3)).ravel()
    assert u.min() > 0 and u.max() < 1
    assert stats.kstest(u, "uniform").pvalue > 1e-3


def test_erfinv32_accuracy():
    x = np.linspace(-1 + 2**-23, 1 - 2**-23, 200_001).astype(np.float32)
    ours = np.asarray(erfinv32(jnp.asarray(x)), dtype=float)
    exact = special.erfinv(x.astype(float))
    assert np.max(np.abs(ours - exact) / np.maximum(np.abs(exact), 1e-30)) < 3e-7


def test_long_counters_do_not_wrap_onto_early_ones():
    """Counters are hashed as they are (a key per block of words): with 4 normals a step
    (two blocks), counter 2**31 once computed counter * 2 + block = 2**32 = 0 (mod 2**32),
    the draws of counter 0."""
    key = _rng.stream_key(_rng.seed_key(8), _rng.STEP)
    paths = np.arange(64, dtype=np.uint32)
    early = np.asarray(normals(key, paths, 0, 4))
    for late in (2**31, 2**31 + 1, 2**32 - 1):
        assert not np.any(np.asarray(normals(key, paths, late, 4)) == early)


def test_tree_draws_depend_on_path_step_and_node_only():
    key = _rng.stream_key(_rng.seed_key(9), _rng.TREE)
    paths = np.arange(500, dtype=np.uint32)
    steps = np.full(500, 7, dtype=np.uint32)
    nodes = np.full(500, 5, dtype=np.uint32)
    full = np.asarray(tree_normals(key, paths, steps, nodes, 3))
    some = np.asarray(tree_normals(key, paths[[4, 400]], steps[:2], nodes[:2], 3))
    np.testing.assert_array_equal(full[:, [4, 400]], some)
    other_node = np.asarray(tree_normals(key, paths, steps, nodes + 1, 3))
    other_step = np.asarray(tree_normals(key, paths, steps + 1, nodes, 3))
    assert not np.any(full == other_node) and not np.any(full == other_step)
    z = full.ravel()
    assert abs(z.mean()) < 4 / np.sqrt(z.size) and abs(z.var() - 1) < 4 * np.sqrt(2 / z.size)
