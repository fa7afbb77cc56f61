"""Import point for JAX inside the package: float64 everywhere.

Every module that uses JAX imports it from here, so `jax_enable_x64` is set before the first
array is made. `import stickslip` alone does not import this module (it stays light).
"""

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402

__all__ = ["jax", "jnp"]
