"""`import stickslip` stays light: JAX and matplotlib load only when needed."""

import subprocess
import sys


def test_import_is_light():
    code = (
        "import sys, stickslip; "
        "heavy = [m for m in ('jax', 'diffrax', 'equinox', 'matplotlib') if m in sys.modules]; "
        "print(','.join(heavy))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""


def test_lazy_names_resolve():
    import stickslip

    for name in ("FrictionModel", "LinearGaussian", "simulate", "simulate_cycles", "Ensemble"):
        assert getattr(stickslip, name) is not None
    assert "simulate" in dir(stickslip)


def test_float64_enabled():
    from stickslip._jax import jax, jnp

    assert jax.config.jax_enable_x64
    assert jnp.zeros(1).dtype == jnp.float64
