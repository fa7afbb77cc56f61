"""Counter-based random numbers: every draw is a function of (seed, stream, path, counter).

A path's noise therefore depends only on the seed and the path's global index, never on how
the paths are grouped into chunks or re-packed into smaller buffers as they finish: results
are independent of the chunk size (a tested promise).

One Threefry-2x32 block hashes the pair (path index, counter) under a key derived from
(seed, stream). Arrays are component-major, `(k, n_paths)`, like the simulator's state.
Normals are made in float32 (erfinv of a 23-bit uniform) and cast to float64: drawing float64
normals was measured as the bottleneck of a JAX step on the target CPU
(8.4e6 against 6.1e7 path-steps/s, DESIGN.md). The float32 normal is exact to about 1e-7
relative and its tails are clipped at |z| = 5.3 (probability 1.2e-7 per draw); the
statistical tests against independent references judge that this is enough.
"""

from __future__ import annotations

import numpy as np

from ._jax import jax, jnp

# Streams: independent families of draws for different purposes.
STEP = 1  # the solver's Gaussian increments
BRIDGE = 2  # uniforms of the Brownian-bridge crossing test
LOCATE = 3  # draws of the crossing-time sampler
ONSET = 4  # PRNG keys handed to model.onset_state
SERIES = 5  # multi-cycle runs
TREE = 6  # bridge samples of the exact stick detection (keyed by step and tree node)
THRESHOLD = 7  # a chain block's strength, drawn when it sticks

_SQRT2 = np.float32(np.sqrt(2.0))


def seed_key(seed: int) -> np.ndarray:
    """The root key of a seed (any integer in [0, 2**64))."""
    seed = int(seed)
    if not 0 <= seed < 2**64:
        raise ValueError("seed must be an integer in [0, 2**64)")
    lo, hi = seed & 0xFFFFFFFF, seed >> 32
    return _host_threefry(np.array([0x5EED5EED, 0x0DDBA11], dtype=np.uint32), lo, hi)


def _host_threefry(key, x0: int, x1: int) -> np.ndarray:
    """`threefry2x32` of two integers in NumPy (no compilation), as a key."""
    one = lambda x: np.array([x], dtype=np.uint32)  # arrays: uint32 sums wrap silently
    w0, w1 = threefry2x32(np.asarray(key, dtype=np.uint32), one(x0), one(x1))
    return np.array([w0[0], w1[0]], dtype=np.uint32)


def stream_key(root, stream: int, cycle: int = 0):
    """Key of one stream (and cycle) under a root key: in NumPy for a NumPy root, else traced
    (the same bits either way)."""
    if isinstance(root, np.ndarray):
        return _host_threefry(root, stream, cycle)
    w0, w1 = threefry2x32(
        jnp.asarray(root, dtype=jnp.uint32), jnp.uint32(stream), jnp.uint32(cycle)
    )
    return jnp.stack([w0, w1])


def stream_keys(root, pairs):
    """`stream_key` of several `(stream, cycle)` pairs under one root, in one NumPy
    evaluation for a NumPy root (~0.1 ms for each key apart)."""
    if not isinstance(root, np.ndarray):
        return [stream_key(root, s, c) for s, c in pairs]
    streams, cycles = (np.array(x, dtype=np.uint32) for x in zip(*pairs, strict=True))
    w0, w1 = threefry2x32(np.asarray(root, dtype=np.uint32), streams, cycles)
    return [np.array([a, b], dtype=np.uint32) for a, b in zip(w0, w1, strict=True)]


def _rotl(x, r: int):
    return (x << np.uint32(r)) | (x >> np.uint32(32 - r))


def threefry2x32(key, x0, x1):
    """Threefry-2x32 with 20 rounds (Salmon et al. 2011), the generator behind JAX's
    default PRNG, written out round by round: JAX lowers its own as a loop over rounds,
    which XLA cannot fuse with the arithmetic around it (measured 2x slower here).
    Bit-identical to `jax.extend.random.threefry_2x32` (tested)."""
    k0, k1 = key[0], key[1]
    ks = (k0, k1, k0 ^ k1 ^ np.uint32(0x1BD11BDA))
    rotations = ((13, 15, 26, 6), (17, 29, 16, 24))
    x0 = x0 + ks[0]
    x1 = x1 + ks[1]
    for i in range(5):
        for r in rotations[i % 2]:
            x0 = x0 + x1
            x1 = _rotl(x1, r) ^ x0
        x0 = x0 + ks[(i + 1) % 3]
        x1 = x1 + ks[(i + 2) % 3] + np.uint32(i + 1)
    return x0, x1


def _block_keys(key, nblocks: int):
    """One key per block of two words: block 0 uses `key` itself, block j > 0 a key hashed
    from it. The counter is then hashed as it is, never multiplied by the number of blocks,
    so that no (counter, block) pair can wrap onto another one on long runs."""
    keys = [key]
    for j in range(1, nblocks):
        w0, w1 = threefry2x32(key, jnp.uint32(j), jnp.uint32(0xB10C))
        keys.append(jnp.stack([w0, w1]))
    return keys


def bits(key, path, counter, nblocks: int):
    """Random 32-bit words, shape `(2 * nblocks, n)`, for paths `path` (uint32, `(n,)`) at
    `counter` (a scalar, or one per path). Words for (path, counter) never depend on which
    other paths are in the batch."""
    key = jnp.asarray(key, dtype=jnp.uint32)
    path = jnp.asarray(path, dtype=jnp.uint32)
    counter = jnp.broadcast_to(jnp.asarray(counter, dtype=jnp.uint32), path.shape)
    words = [threefry2x32(k, path, counter) for k in _block_keys(key, nblocks)]
    return jnp.stack([w[0] for w in words] + [w[1] for w in words])


def candidate_key(key, path, step):
    """The key of one candidate step's refinement tree (two words, each `(n,)`): a function
    of (key, path, step) alone, computed once per candidate and carried with its intervals."""
    key = jnp.asarray(key, dtype=jnp.uint32)
    return threefry2x32(
        key, jnp.asarray(path, dtype=jnp.uint32), jnp.asarray(step, dtype=jnp.uint32)
    )


def node_normals(ckey, node, k: int):
    """`k` standard normals per interval for node `node` (uint32, one per interval) of the
    tree whose `candidate_key` words are `ckey` (two arrays): two Threefry blocks for k <= 4
    (hashing (step, node) and then the path cost a third block: 3-7 % of a refinement pass)."""
    sub = jnp.stack([jnp.asarray(w, dtype=jnp.uint32) for w in ckey])  # a key per interval
    node = jnp.asarray(node, dtype=jnp.uint32)
    nblocks = (k + 1) // 2
    blocks = [threefry2x32(sub, node, jnp.full(node.shape, j, jnp.uint32)) for j in range(nblocks)]
    b = jnp.stack([w[0] for w in blocks] + [w[1] for w in blocks])
    return _to_normals(b[:k])


def tree_normals(key, path, step, node, k: int):
    """`k` standard normals per path for node `node` (uint32, one per path) of the refinement
    tree of step `step` (one per path): a function of (key, path, step, node) alone."""
    return node_normals(candidate_key(key, path, step), node, k)


# Giles (2010), "Approximating the erfinv function", single precision: the same
# approximation as XLA's, written with both branches evaluated and one final select, so that
# it fuses into a single elementwise kernel (XLA's own erf_inv was left as ~20 unfused
# passes over memory inside the simulator's loop; measured).
_ERFINV_CENTRAL = (
    2.81022636e-08,
    3.43273939e-07,
    -3.5233877e-06,
    -4.39150654e-06,
    0.00021858087,
    -0.00125372503,
    -0.00417768164,
    0.246640727,
    1.50140941,
)
_ERFINV_TAIL = (
    -0.000200214257,
    0.000100950558,
    0.00134934322,
    -0.00367342844,
    0.00573950773,
    -0.0076224613,
    0.00943887047,
    1.00167406,
    2.83297682,
)


def erfinv32(x):
    """Inverse error function in float32 (relative error < 3e-7 on (-1, 1))."""
    w = -jnp.log((1.0 - x) * (1.0 + x))
    wc = w - 2.5
    wt = jnp.sqrt(w) - 3.0
    pc = jnp.float32(_ERFINV_CENTRAL[0])
    pt = jnp.float32(_ERFINV_TAIL[0])
    for a, b in zip(_ERFINV_CENTRAL[1:], _ERFINV_TAIL[1:], strict=True):
        pc = jnp.float32(a) + pc * wc
        pt = jnp.float32(b) + pt * wt
    return jnp.where(w < 5.0, pc, pt) * x


def normals(key, path, counter, k: int):
    """`k` standard normals per path, float64 from float32, shape `(k, n)`."""
    return _to_normals(bits(key, path, counter, (k + 1) // 2)[:k])


def _to_normals(b):
    f = jax.lax.bitcast_convert_type((b >> 9) | jnp.uint32(0x3F800000), jnp.float32) - 1.0
    # f is uniform on {0, ..., 1 - 2**-23}; u below is symmetric in (-1, 1), so E[z] = 0.
    u = 2.0 * f - 1.0 + jnp.float32(2.0**-23)
    return (_SQRT2 * erfinv32(u)).astype(jnp.float64)


def uniforms(key, path, counter, k: int):
    """`k` uniforms per path in the open interval (0, 1), float64 with 32 random bits,
    shape `(k, n)`."""
    b = bits(key, path, counter, (k + 1) // 2)[:k]
    return (b.astype(jnp.float64) + 0.5) * (1.0 / 2.0**32)


def path_keys(key, path, counter):
    """One JAX PRNG key per path (for model code written with `jax.random`)."""
    b = bits(key, path, counter, 1)
    return jax.random.wrap_key_data(b.T, impl="threefry2x32")
