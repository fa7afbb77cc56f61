r"""The admissible ranges of a slip model's scales, shared by the plugins.

A slip phase with rate $\omega_0$ (its oscillation), damping and noise rates, a length scale
$\ell$ (the threshold $x_0$, or $F_s/k$) and a noise intensity $D$ is refused where it is
built, with the reason, when its numbers leave what float64 and the exact propagators can
hold:

- **rates** ($\omega_0$, $\zeta$, $1/\tau$) at most `RATE_MAX` = 1e12 per time unit: the
  exact propagators sum 20 terms of $A^k B B^\top$ over one lag, whose entries grow like
  $\omega_0^{2k}$ (measured: a model scaled to rate 1e12 runs; at 1e14 the covariance
  tables overflow, `LinAlgError`). Rescale time for faster models;
- **noise**: $D = 0$, or the dimensionless level $\hat D = D / (\omega_0^3 \ell^2)$ (the
  velocity variance the noise adds over one oscillation, $D/\omega_0$, against the slip's
  squared velocity scale $(\omega_0 \ell)^2$) between `NOISE_MIN` = 1e-100 (below it the
  covariances underflow float64, `LinAlgError` at 1e-300: use D = 0) and `NOISE_MAX` =
  1e12 (the noise's velocity spread a million times the slip's: no stick-slip structure
  left, and at 1e300 the covariances overflow).

The checks work on logarithms of Python floats, so they raise no overflow and print no
NumPy warnings whatever the values.
"""

from __future__ import annotations

import math

from stickslip import ParameterError

RATE_MAX = 1e12
NOISE_MIN = 1e-100
NOISE_MAX = 1e12
# The driving speed in the slip's own units, v_b / (omega0 l): a stick lasts about l / v_b, so
# at 1e-12 one stick spans 1e12 slip time scales (and at 1e-300 it overflows to inf: found by
# tests/test_fuzz.py); at 1e12 the belt outruns every slip (no stick-slip structure left).
SPEED_MIN = 1e-12
SPEED_MAX = 1e12


def check_rate(owner: str, name: str, rate: float, label: str, value) -> None:
    """Refuse a rate (per time unit) above `RATE_MAX`; `label` says how it follows from
    the parameter `name` (e.g. `"1/tau"`)."""
    if not rate <= RATE_MAX:
        raise ParameterError(
            owner,
            name,
            f"gives the rate {label} = {rate:.3g} per time unit, above {RATE_MAX:g}: the exact "
            "propagators overflow float64 at such rates (rescale time)",
            value,
        )


def check_speed(owner: str, v_b: float, omega0: float, length: float, label: str) -> None:
    r"""Refuse a driving speed whose level `v_b / label` (`label` spells the velocity scale
    $\omega_0 \ell$ in the model's own parameters) is outside [`SPEED_MIN`, `SPEED_MAX`]."""
    log = math.log10(v_b) - math.log10(omega0) - math.log10(length)
    if math.log10(SPEED_MIN) <= log <= math.log10(SPEED_MAX):
        return
    level = 10.0 ** max(min(log, 300.0), -300.0)
    why = (
        f"below {SPEED_MIN:g}: a stick would last {1 / level:.3g} slip time scales"
        if level < SPEED_MIN
        else f"above {SPEED_MAX:g}: the belt would outrun every slip"
    )
    raise ParameterError(
        owner,
        "v_b",
        f"gives the speed level v_b/({label}) = {level:.3g}, {why}; admissible: "
        f"{SPEED_MIN:g} <= v_b/({label}) <= {SPEED_MAX:g}",
        v_b,
    )


def noise_level(D: float, omega0: float, length: float) -> float:
    r"""$\hat D = D / (\omega_0^3 \ell^2)$, computed without overflow (0 for D = 0)."""
    if D == 0.0:
        return 0.0
    log = math.log10(D) - 3.0 * math.log10(omega0) - 2.0 * math.log10(length)
    return 10.0 ** max(min(log, 300.0), -300.0)  # (shown clipped to float64's range)


def check_noise(owner: str, D: float, omega0: float, length: float, label: str) -> None:
    """Refuse a noise intensity `D` whose level `D / label` (`label` spells the scale
    $\\omega_0^3 \\ell^2$ in the model's own parameters) is outside
    [`NOISE_MIN`, `NOISE_MAX`]; D = 0 (no noise) is always admissible."""
    if D == 0.0:
        return
    level = noise_level(D, omega0, length)
    if NOISE_MIN <= level <= NOISE_MAX:
        return
    if level > NOISE_MAX:
        why = (
            f"above {NOISE_MAX:g}: the noise's velocity spread would swamp the slip's "
            "(no stick-slip structure left)"
        )
    else:
        why = f"below {NOISE_MIN:g}: the covariances underflow float64 (use D = 0 for no noise)"
    raise ParameterError(
        owner,
        "D",
        f"gives the noise level D/({label}) = {level:.3g}, {why}; admissible: D = 0 or "
        f"{NOISE_MIN:g} <= D/({label}) <= {NOISE_MAX:g}",
        D,
    )
