"""The benchmarks' normal threshold law by its truncated moments (`benchmarks/
truncated_moments.py`): its map to the untruncated normal against SciPy's truncated normal,
and its draws against that law. An experiment's helper: in the slow tier (JAX's first
traces of the bisection take seconds)."""

from __future__ import annotations

import importlib.util
import pathlib
import sys

import numpy as np
import pytest
from scipy import stats

pytestmark = pytest.mark.slow

_spec = importlib.util.spec_from_file_location(
    "truncated_moments",
    pathlib.Path(__file__).resolve().parents[1] / "benchmarks" / "truncated_moments.py",
)
tm = importlib.util.module_from_spec(_spec)
sys.modules.setdefault(_spec.name, tm)
_spec.loader.exec_module(tm)


@pytest.mark.parametrize("mu, sigma", [(1.0, 0.626), (0.2, 1.0), (-1.0, 0.5), (3.0, 0.1)])
def test_moments_map_back_to_the_normal_that_has_them(mu, sigma):
    law = stats.truncnorm(-mu / sigma, np.inf, loc=mu, scale=sigma)
    m, s = tm.moments(mu, sigma)
    assert m == pytest.approx(law.mean(), rel=1e-12)
    assert s == pytest.approx(law.std(), rel=1e-10)
    back = tm.underlying(m, s)
    assert float(back[0]) == pytest.approx(mu, abs=1e-9 * max(1, abs(mu)))
    assert float(back[1]) == pytest.approx(sigma, rel=1e-9)


def test_draws_follow_the_truncated_law():
    """20 000 draws: their mean and sd within 4 sampling sds of the law's, and a KS test
    against SciPy's truncated normal of the same moments."""
    import jax

    m, s = tm.moments(1.0, 0.626)
    law = tm.TruncatedNormalMoments(mean=m, cv=s / m)
    x = np.asarray(jax.vmap(law.sample)(jax.random.split(jax.random.key(3), 20_000)))
    assert abs(x.mean() - m) < 4 * s / np.sqrt(x.size)
    assert abs(x.std() - s) < 4 * s / np.sqrt(2 * x.size)
    assert stats.kstest(x, law.frozen().cdf).pvalue > 1e-3
    assert law.frozen().mean() == pytest.approx(m, rel=1e-10)
