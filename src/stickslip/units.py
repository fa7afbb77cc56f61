r"""A spring-pulled slider stated in SI units, and its models in the paper's variables.

`Slider(mass, stiffness, v_b, static_friction, kinetic_friction, ...)` states an experiment
in kilograms, newtons, metres and seconds; it derives the dimensionless parameters of the
`langevin` model (or of `random-threshold`, for a random static friction), builds that model
through the public registry, and gives its results back in seconds, metres and newtons.

**The mapping** (docs/units.md derives it). A slider of mass $m$ is pulled at speed $V$
through a spring of stiffness $k$; $e$ is the spring's extension, $F = k e$ the force it
carries (what a load cell on the spring reads). Kinetic friction $F_k$ and a viscous force
$c\dot X$ (on the slider's velocity $\dot X$ over the track) act while it slides, a random
force $\xi(t)$ with it. With $x = e - (F_k + cV)/k$ and $v = \dot e = V - \dot X$:

$$\dot x = v, \qquad \dot v = -\omega_0^2 x - \zeta v + \eta, \qquad
\omega_0 = \sqrt{k/m},\ \zeta = c/m,\ \eta = -\xi/m,$$

eq. (8) exactly. A slip starts where the spring force reaches the static friction $F_s$, at
$x_0 = (F_s - F_k - cV)/k$ with $v = V$ (slider at rest), and ends when the slider stops,
$v = V$ again: the paper's stick, $v_b = V$. The stick loads the spring at $\dot e = V$
back to the threshold (eq. 9). Measured in the units $1/\omega_0$ (time) and $x_0$ (length)
the model has $\omega_0 = x_0 = 1$ and the dimensionless

$$\hat\zeta = \frac{c}{m\omega_0}, \quad \hat v_b = \frac{V}{\omega_0 x_0}, \quad
\hat D = \frac{S}{m^2\omega_0^3 x_0^2}, \quad \hat\tau = \omega_0\tau_c,$$

with $S$ the friction noise's intensity (N² s) and $\tau_c$ its correlation time (s).
Results: a slip time $\hat T$ is $\hat T/\omega_0$ seconds; the paper's slip distance
$\hat d = \hat x_0 - \hat x_{sl}$ is $\hat d\,x_0$ metres of the *spring's extension*, i.e.
a force drop of $k x_0 \hat d$ newtons (the slider itself travels that plus $V T_{sl}$).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from ._errors import ParameterError, check_nonnegative, check_positive, check_real
from .quantities import get as quantity
from .quantities import names as quantity_names

__all__ = ["Scales", "Slider", "SliderCycles", "noise_free_slip"]

_OWNER = "Slider"

# The model's time step when none is given, in units of 1/omega0: about 300 steps per
# oscillation. With exact Gaussian steps dt only sets how often the stick is looked for
# (exact in law at any step, docs/simulator.md); at this step the noise-free stick is
# located to ~1e-12 (tested against the closed form).
DEFAULT_STEP = 0.02
# The longest slip followed when no t_max is given, in units of 1/omega0: about 16
# oscillations, i.e. a slip that missed its stick opportunity a dozen times.
DEFAULT_HORIZON = 100.0
# A step above one radian of the oscillation (dt > 1/omega0) is taken for a unit slip: the
# slip itself lasts about pi/omega0 and the stick is looked for once a step.
MAX_STEP = 1.0

# Laws of a random static friction that map exactly onto the random-threshold plugin's laws
# of x0 = (F_s - F_k - c V)/k (an affine map keeps a normal normal and a uniform uniform;
# a lognormal or Weibull F_s shifted by F_k + c V is neither).
_THRESHOLD_LAWS = {"normal": ("mean", "sd"), "uniform": ("low", "high")}
# The SI values `Slider.model_parameters` maps into a slider's model units (a joint fit's
# parameter names)
MODEL_SI_NAMES = ("mass", "damping", "noise", "noise_time", "static_friction",
                  "kinetic_friction", "threshold.mean", "threshold.sd", "threshold.low",
                  "threshold.high")  # fmt: skip

# Plugin parameter -> the Slider's field it comes from (to name the SI field in errors).
_SI_FIELD = {
    "omega0": "mass",
    "zeta": "damping",
    "D": "noise",
    "v_b": "v_b",
    "x0": "static_friction",
    "tau": "noise_time",
    "threshold": "threshold",
}

# A Slider's per-cycle columns (their units and dimensions: `stickslip.quantities`).
COLUMNS = quantity_names("slider")


@dataclasses.dataclass(frozen=True)
class Scales:
    r"""The units of the dimensionless model, in SI.

    - `omega0` $=\sqrt{k/m}$ (rad/s);
    - `time` $= 1/\omega_0$ (s);
    - `length` $= x_0 = (F_s - F_k - cV)/k$ (m): the spring's extension from the level at
      which it balances sliding friction to the threshold (the reference threshold for a
      random static friction);
    - `velocity` $= \omega_0 x_0$ (m/s);
    - `force` $= k x_0$ (N): a unit of force *differences* (a force drop);
    - `force_offset` $= F_k + cV$ (N): the spring force at $x = 0$;
    - `noise` $= m^2\omega_0^3 x_0^2$ (N² s): the unit of the noise intensity $S$.
    """

    omega0: float
    time: float
    length: float
    velocity: float
    force: float
    force_offset: float
    noise: float

    @classmethod
    def si(cls, stiffness: float) -> Scales:
        """The units of a model written in SI (a creeping slider: rate-and-state) as a
        force trace's cycles meet it: seconds, metres, and forces over the spring's
        `stiffness` (N/m), so that a force drop reads as the extension it releases (its
        `slip_distance`, m) and the force trace as the spring's extension."""
        k = check_positive("Scales.si", "stiffness", stiffness)
        return cls(omega0=1.0, time=1.0, length=1.0, velocity=1.0, force=float(k),
                   force_offset=0.0, noise=1.0)  # fmt: skip


@dataclasses.dataclass(frozen=True, eq=False)
class SliderCycles:
    """Per-cycle results of a `Slider` in SI units.

    - `table`: a dict of equal-length arrays, one row per cycle (per simulated path),
      `nan` where the path had not stuck by `t_max`: `slip_time` (s), `slip_distance` (m,
      the paper's $d$: the change of the spring's extension over the slip, = force drop /
      k), `stick_time` (s), `period` (s), `peak_force` (N, the spring force at the
      release: the static friction of that cycle), `force_drop` (N, release less stick)
      and `slider_travel` (m, how far the slider itself moved: $d + V T_{sl}$);
    - `units`: the unit of each column;
    - `info`: the slider, the model's parameters and the run's settings (dt and t_max in
      seconds and in model units);
    - `ensemble`: the dimensionless `Ensemble` behind it (None for the noise-free cycle).
    """

    table: dict[str, np.ndarray]
    units: dict[str, str]
    info: dict[str, Any]
    ensemble: Any = None

    def __len__(self) -> int:
        return int(self.table["slip_time"].size)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.table[name]

    def mean(self, name: str) -> tuple[float, float]:
        """Mean of a column over the finite rows, with its standard error (SI units)."""
        x = np.asarray(self.table[name], float)
        x = x[np.isfinite(x)]
        if x.size == 0:
            return float("nan"), float("nan")
        se = float(np.std(x, ddof=1) / math.sqrt(x.size)) if x.size > 1 else float("nan")
        return float(np.mean(x)), se

    def __repr__(self) -> str:
        m, _ = self.mean("slip_time")
        return f"SliderCycles(n={len(self)}, mean slip_time={m:.4g} s)"


@dataclasses.dataclass(frozen=True)
class Slider:
    r"""A slider pulled through a spring, in SI units.

    **Arguments:**

    - `mass` $m$ (kg), `stiffness` $k$ (N/m), `v_b` the driving speed $V$ (m/s): all > 0;
    - `static_friction` $F_s$ (N): the spring force at which a stick releases; None when
      `threshold` gives a random one;
    - `kinetic_friction` $F_k$ (N, $\ge 0$): the friction force while sliding; a slip
      needs $F_k + cV < F_s$;
    - `damping` $c$ (kg/s, $\ge 0$): a viscous force $c\dot X$ on the slider's velocity
      over the track. The models need $c > 0$ (their $\zeta > 0$); at $c = 0$ the
      noise-free cycle is still given in closed form (`deterministic()`);
    - `noise` $S$ (N² s, $\ge 0$): the intensity of a random friction force $\xi$,
      $\langle\xi(t)\xi(s)\rangle = (S/\tau_c)\,e^{-|t-s|/\tau_c}$ (an Ornstein-Uhlenbeck
      force of rms $\sqrt{S/\tau_c}$ newtons; $2S\,\delta(t-s)$ as $\tau_c \to 0$);
    - `noise_time` $\tau_c$ (s, > 0): the noise's correlation time; required with
      `noise > 0` (white noise makes every slip re-stick at once: docs/simulator.md);
    - `threshold`: a random static friction, drawn afresh at each release, as
      `(law, params)` in newtons: `("normal", {"mean": ..., "sd": ...})` (truncated to
      $F_s > F_k + cV$) or `("uniform", {"low": ..., "high": ...})` (with
      low $> F_k + cV$). The model is then `random-threshold`.

    Invalid values raise a `ParameterError` naming the field; so does a slider whose
    model the plugin refuses (e.g. a noise level or a correlation time out of its
    admissible range: often a unit off by orders), and a noise-free slider that never
    sticks again (above the critical speed, or overdamped).

    ```python
    from stickslip.units import Slider
    s = Slider(mass=0.0307, stiffness=168.0, v_b=42e-6, static_friction=0.0964,
               kinetic_friction=0.0911, damping=1e-3, noise=1e-9, noise_time=1e-3)
    s.dimensionless()   # {'omega0': 1.0, 'zeta': ..., 'D': ..., 'v_b': ..., 'x0': 1.0, 'tau': ...}
    print(s.describe())  # the derived parameters with their formulas
    run = s.simulate(200, seed=0)  # per-cycle results in s, m, N
    ```
    """

    mass: float
    stiffness: float
    v_b: float
    static_friction: float | None
    kinetic_friction: float
    damping: float = 0.0
    noise: float = 0.0
    noise_time: float | None = None
    threshold: tuple[str, dict[str, float]] | None = None

    def __post_init__(self):
        def put(name, value):  # (frozen: store the checked, plain-float values)
            object.__setattr__(self, name, value)

        for name in ("mass", "stiffness", "v_b"):
            put(name, check_positive(_OWNER, name, getattr(self, name)))
        for name in ("kinetic_friction", "damping", "noise"):
            put(name, check_nonnegative(_OWNER, name, getattr(self, name)))
        put("noise_time", check_positive(_OWNER, "noise_time", self.noise_time, allow_none=True))
        if self.noise > 0 and self.noise_time is None:
            raise ParameterError(
                _OWNER, "noise_time", "is required with noise > 0: white friction noise makes "
                "every slip re-stick at once (docs/simulator.md); give its correlation time in s",
            )  # fmt: skip
        offset = self.kinetic_friction + self.damping * self.v_b
        if not math.isfinite(offset):
            raise ParameterError(_OWNER, "damping", "gives c V = inf", self.damping)
        # (a stiffness that is not sqrt-able or a sqrt(k/m) that overflows fails here)
        omega0 = math.sqrt(self.stiffness) / math.sqrt(self.mass)
        if not (math.isfinite(omega0) and omega0 > 0):
            raise ParameterError(_OWNER, "mass", f"gives omega0 = sqrt(k/m) = {omega0:g}")
        zeta = self.damping / (self.mass * omega0)
        if self.threshold is None:
            put("static_friction", check_positive(_OWNER, "static_friction", self.static_friction))
            self._check_drop("static_friction", self.static_friction, offset, zeta)
        else:
            if self.static_friction is not None:
                raise ParameterError(
                    _OWNER, "static_friction", "must be None when a random threshold is given: "
                    "the law in `threshold` states the static friction", self.static_friction,
                )  # fmt: skip
            put("threshold", self._check_threshold(self.threshold, offset, zeta))
        length = (self._reference_friction() - offset) / self.stiffness
        if not length > 0:  # an underflow of the division
            raise ParameterError(
                _OWNER, "stiffness", f"gives the length unit (F_s - F_k - c V)/k = {length:g} m"
            )
        # The scales, and every dimensionless number finite (a unit off by hundreds of orders
        # overflows here rather than in the model).
        for name, value in self._dimensionless(omega0, length).items():
            if isinstance(value, float) and not math.isfinite(value):
                field = _SI_FIELD.get(name, name)
                raise ParameterError(
                    _OWNER, field, f"gives the model's {name} = {value}: not a finite number"
                )
        if self.damping > 0:
            self.model()  # the plugin's own checks, re-named to this slider's fields
        if self.noise == 0.0 and not math.isfinite(self._noise_free_slip()[0]):
            if zeta >= 2.0:
                raise ParameterError(
                    _OWNER, "damping", f"gives zeta = c/(m omega0) = {zeta:.4g} >= 2: the "
                    "noise-free slider is overdamped and never sticks again (no stick-slip)",
                    self.damping,
                )  # fmt: skip
            raise ParameterError(
                _OWNER, "v_b", f"gives v_b = V/(omega0 x0) = {self.v_b / (omega0 * length):.4g}, "
                f"above the critical speed at zeta = {zeta:.4g}: the noise-free slider slides "
                "steadily and never sticks again (no stick-slip; is v_b in m/s?)", self.v_b,
            )  # fmt: skip

    # -- validation helpers --------------------------------------------------------------
    def _check_drop(self, name, value, offset, zeta):
        """A static friction must exceed the sliding force F_k + c V (x0 > 0)."""
        if value > offset:
            return
        if name != "static_friction":
            raise ParameterError(
                _OWNER, name, f"must be above kinetic_friction + damping * v_b = {offset:.6g} N "
                "(the law may not put static friction at or below the sliding friction)", value,
            )  # fmt: skip
        if self.kinetic_friction >= value:
            raise ParameterError(
                _OWNER, "kinetic_friction", f"must be below static_friction = {value:.6g} N: "
                "the drop F_s - F_k is what starts a slip", self.kinetic_friction,
            )  # fmt: skip
        # The viscous force at the driving speed fills the drop: x0 <= 0, the slider slides
        # on after a release. At zeta >= 2 no speed gives stick-slip (blame the damping),
        # else the speed is too high.
        field = "damping" if zeta >= 2.0 else "v_b"
        viscous, drop = offset - self.kinetic_friction, value - self.kinetic_friction
        raise ParameterError(
            _OWNER, field, f"gives a viscous force damping * v_b = {viscous:.4g} N, not below "
            f"the friction drop F_s - F_k = {drop:.4g} N: x0 = (F_s - F_k - c V)/k <= 0, no "
            f"stick-slip (zeta = c/(m omega0) = {zeta:.4g}; is {field} in SI units?)",
            getattr(self, field),
        )  # fmt: skip

    def _check_threshold(self, threshold, offset, zeta):
        ok = isinstance(threshold, (tuple, list)) and len(threshold) == 2
        if not ok or not isinstance(threshold[1], dict):
            raise ParameterError(
                _OWNER, "threshold", "must be (law, params), e.g. ('normal', {'mean': 0.1, "
                "'sd': 0.005}) in newtons",
            )  # fmt: skip
        law, params = threshold
        if law in ("lognormal", "weibull"):
            raise ParameterError(
                _OWNER, "threshold", f"'{law}' cannot be mapped: the model's threshold is "
                "x0 = (F_s - F_k - c V)/k, and a shifted lognormal or Weibull F_s is not of "
                "the same family; use 'normal' or 'uniform' (or the random-threshold model "
                "directly)", law,
            )  # fmt: skip
        if law not in _THRESHOLD_LAWS:
            raise ParameterError(_OWNER, "threshold", "must be 'normal' or 'uniform'", law)
        names = _THRESHOLD_LAWS[law]
        for key in params:
            if key not in names:
                raise ParameterError(
                    _OWNER, f"threshold.{key}", f"is not a parameter of the {law} law "
                    f"({', '.join(names)})",
                )  # fmt: skip
        out = {}
        for key in names:
            if key not in params:
                raise ParameterError(_OWNER, f"threshold.{key}", f"is required by the {law} law")
            out[key] = check_real(_OWNER, f"threshold.{key}", params[key])
        if law == "normal":
            check_nonnegative(_OWNER, "threshold.sd", out["sd"])
            self._check_drop("threshold.mean", out["mean"], offset, zeta)
        else:
            self._check_drop("threshold.low", out["low"], offset, zeta)
            if out["high"] < out["low"]:
                raise ParameterError(
                    _OWNER, "threshold.high", f"must be >= low = {out['low']}", out["high"]
                )
        return (law, out)

    def _reference_friction(self) -> float:
        """The static friction that sets the length unit: F_s, or the law's centre (the
        normal's mean, the uniform's midpoint)."""
        if self.threshold is None:
            return self.static_friction
        law, p = self.threshold
        return p["mean"] if law == "normal" else 0.5 * (p["low"] + p["high"])

    # -- scales and the dimensionless parameters ------------------------------------------
    @property
    def scales(self) -> Scales:
        """The model's units in SI (`Scales`)."""
        omega0 = math.sqrt(self.stiffness) / math.sqrt(self.mass)
        offset = self.kinetic_friction + self.damping * self.v_b
        length = (self._reference_friction() - offset) / self.stiffness
        return Scales(
            omega0=omega0,
            time=1.0 / omega0,
            length=length,
            velocity=omega0 * length,
            force=self.stiffness * length,
            force_offset=offset,
            noise=self.mass**2 * omega0**3 * length**2,
        )

    @property
    def model_name(self) -> str:
        """`"langevin"`, or `"random-threshold"` with a random static friction."""
        return "langevin" if self.threshold is None else "random-threshold"

    def _dimensionless(self, omega0, length):
        out: dict[str, Any] = {"omega0": 1.0, "zeta": self.damping / (self.mass * omega0)}
        # D = S / (m^2 omega0^3 x0^2), in logarithms: no overflow on the way to a huge value
        if self.noise == 0.0:
            out["D"] = 0.0
        else:
            log = (
                math.log(self.noise) - 2 * math.log(self.mass)
                - 3 * math.log(omega0) - 2 * math.log(length)
            )  # fmt: skip
            out["D"] = math.exp(log) if log < 709.0 else math.inf
        out["v_b"] = self.v_b / (omega0 * length)
        if self.threshold is None:
            out["x0"] = 1.0
        else:
            law, p = self.threshold
            offset = self.kinetic_friction + self.damping * self.v_b
            unit = self.stiffness * length
            if law == "normal":
                params = {"mean": (p["mean"] - offset) / unit, "sd": p["sd"] / unit}
            else:
                params = {"low": (p["low"] - offset) / unit, "high": (p["high"] - offset) / unit}
            out["threshold"] = law
            out["threshold_params"] = params
        out["tau"] = None if self.noise_time is None else omega0 * self.noise_time
        return out

    def dimensionless(self) -> dict[str, Any]:
        r"""The model's parameters in the paper's variables (units $1/\omega_0$ and $x_0$):
        `omega0` (= 1), `zeta` $= c/(m\omega_0)$, `D` $= S/(m^2\omega_0^3 x_0^2)$, `v_b`
        $= V/(\omega_0 x_0)$, `tau` $= \omega_0\tau_c$ (None without noise time), and `x0`
        (= 1) or, with a random threshold, `threshold` and `threshold_params`
        (`(F - F_k - cV)/(k x_0)` for a force F, `sd / (k x_0)` for a spread)."""
        s = self.scales
        return self._dimensionless(s.omega0, s.length)

    def model(self):
        """The `langevin` (or `random-threshold`) model with `dimensionless()`'s parameters,
        built through `stickslip.get_model`. Needs `damping > 0` (the plugins' $\\zeta > 0$)."""
        from ._registry import get_model

        if self.damping == 0.0:
            raise ParameterError(
                _OWNER, "damping", "must be > 0 to build a model: the langevin and "
                "random-threshold plugins need zeta = c/(m omega0) > 0 (the noise-free "
                "undamped cycle is given in closed form by Slider.deterministic())", 0.0,
            )  # fmt: skip
        params = self.dimensionless()
        try:
            return get_model(self.model_name)(**params)
        except ParameterError as err:
            parameter = err.parameter.split(".")
            if parameter[0] == "threshold_params":
                field = ".".join(["threshold", *parameter[1:]])
            else:
                field = _SI_FIELD.get(parameter[0], err.parameter)
            raise ParameterError(
                _OWNER, field, f"gives a model that the {self.model_name} plugin refuses: "
                f"{err.parameter} {err.reason}",
            ) from None  # fmt: skip

    def si_parameters(self, params: dict[str, Any]) -> dict[str, Any]:
        r"""The SI values of model parameters (e.g. a fit's estimates, or the ends of its
        intervals: each map is monotone): `zeta` -> `damping` (kg/s), `D` -> `noise`
        (N² s), `tau` -> `noise_time` (s), `v_b` -> `v_b` (m/s), `x0` -> `static_friction`
        (N), `threshold_params` -> `threshold` (N), in this slider's units ($\omega_0$,
        $x_0$, $k$ fixed; the force offset $F_k + cV$ from `damping` and `v_b` given
        here or this slider's own).

        `omega0` other than 1 is a natural frequency $\omega_0\sqrt{k/m}$ other than this
        slider's (a fitted one): it maps to the effective `mass` $m/\omega_0^2$ (kg, at
        this stiffness; decreasing in `omega0`), which then also sets `damping`
        ($\zeta m_{eff}\omega_0$ of this slider) and `noise` ($D m_{eff}^2 \omega_0^3
        x_0^2$): the model's time unit stays this slider's $1/\omega_0$. Unknown names
        raise a `ParameterError`."""
        s = self.scales
        out: dict[str, Any] = {}
        known = {"omega0", "zeta", "D", "tau", "v_b", "x0", "threshold", "threshold_params"}
        for key in params:
            if key not in known:
                raise ParameterError(
                    "Slider.si_parameters", key, f"is not a parameter of {self.model_name}"
                )
        mass = self.mass
        if "omega0" in params:
            omega0 = check_positive("Slider.si_parameters", "omega0", params["omega0"])
            # the model's dv/dt = -omega0^2 x - zeta v + eta in this slider's units: the
            # spring's k over an effective mass m / omega0^2
            mass = self.mass / omega0**2
            out["mass"] = mass
        if "zeta" in params:
            out["damping"] = params["zeta"] * mass * s.omega0
        if "D" in params:
            out["noise"] = params["D"] * s.noise * (mass / self.mass) ** 2
        if "tau" in params:
            out["noise_time"] = None if params["tau"] is None else params["tau"] * s.time
        if "v_b" in params:
            out["v_b"] = params["v_b"] * s.velocity
        offset = self.kinetic_friction + out.get("damping", self.damping) * out.get("v_b", self.v_b)
        if "x0" in params:
            out["static_friction"] = offset + params["x0"] * s.force
        if "threshold_params" in params:
            law = params.get("threshold", None if self.threshold is None else self.threshold[0])
            p = params["threshold_params"]
            if law == "normal":
                out["threshold"] = (law, {"mean": offset + p["mean"] * s.force,
                                          "sd": p["sd"] * s.force})  # fmt: skip
            elif law == "uniform":
                out["threshold"] = (law, {"low": offset + p["low"] * s.force,
                                          "high": offset + p["high"] * s.force})  # fmt: skip
            else:
                raise ParameterError(
                    "Slider.si_parameters", "threshold", "must be 'normal' or 'uniform'", law
                )
        return out

    def model_parameters(self, si: dict[str, Any] | None = None) -> dict[str, Any]:
        r"""The model's parameters, in this slider's units, of a slider that differs from
        this one by the SI values `si` (the inverse of `si_parameters`): this slider's
        spring and speed with another mass, damping, noise or friction, as a model fitted
        in this slider's units sees it (a joint fit of several runs maps one physical
        parameter set to each run's units this way).

        `si` may set `mass` (kg: `omega0` $= \sqrt{m/m'}$), `damping` (kg/s), `noise`
        (N² s), `noise_time` (s), `static_friction`, `kinetic_friction` (N), and a
        random threshold's `threshold.mean`, `threshold.sd` (a normal law) or
        `threshold.low`, `threshold.high` (uniform) in N; what it leaves out is this
        slider's. `model_parameters()` is `dimensionless()` to rounding. Unknown names
        raise a `ParameterError`."""
        owner = "Slider.model_parameters"
        si = dict(si or {})
        for key in si:
            if key not in MODEL_SI_NAMES:
                raise ParameterError(
                    owner, key, "is not a slider parameter; one of " + ", ".join(MODEL_SI_NAMES)
                )
        s = self.scales
        mass = check_positive(owner, "mass", si.get("mass", self.mass))
        damping = si.get("damping", self.damping)
        noise = si.get("noise", self.noise)
        noise_time = si.get("noise_time", self.noise_time)
        kinetic = si.get("kinetic_friction", self.kinetic_friction)
        out: dict[str, Any] = {
            "omega0": math.sqrt(self.mass / mass),
            "zeta": damping / (mass * s.omega0),
            "D": noise / (s.noise * (mass / self.mass) ** 2),
            "v_b": self.v_b / s.velocity,
            "tau": None if noise_time is None else noise_time / s.time,
        }
        offset = kinetic + damping * self.v_b
        law_keys = [k for k in si if k.startswith("threshold.")]
        if law_keys:
            law = "normal" if {"threshold.mean", "threshold.sd"} & set(law_keys) else "uniform"
            if self.threshold is not None and self.threshold[0] == law:
                given = self.threshold[1]
            else:  # a fixed static friction: the normal law's mean
                given = {"mean": self.static_friction} if law == "normal" else {}
            fields = _THRESHOLD_LAWS[law]
            p = {f: si.get(f"threshold.{f}", given.get(f)) for f in fields}
            missing = [f"threshold.{f}" for f, v in p.items() if v is None]
            if missing:
                raise ParameterError(owner, missing[0], f"is needed with the {law} law's others")
        elif self.threshold is not None:
            law, p = self.threshold
        else:
            law = None
        if law is None:
            static = si.get("static_friction", self.static_friction)
            out["x0"] = (static - offset) / s.force
        elif law == "normal":
            out["threshold"] = law
            out["threshold_params"] = {"mean": (p["mean"] - offset) / s.force,
                                       "sd": p["sd"] / s.force}  # fmt: skip
        else:
            out["threshold"] = law
            out["threshold_params"] = {"low": (p["low"] - offset) / s.force,
                                       "high": (p["high"] - offset) / s.force}  # fmt: skip
        return out

    # -- a measured trace and a fit -------------------------------------------------------
    @classmethod
    def from_cycles(
        cls,
        cycles,
        mass: float,
        *,
        stiffness: float | None = None,
        v_b: float | None = None,
        zeta: float = 1e-3,
    ) -> Slider:
        r"""The reference slider of a measured force trace: the units in which a model of
        its cycles is fitted (`fit(..., cycles, scales=slider)`) and in which the fit's
        parameters are read back (`si_table`).

        **Arguments:**

        - `cycles`: the `Cycles` of `extract_cycles` on a force trace (or `read_cycles` of
          the table `stickslip cycles` wrote): its `peak_force` and `force_drop` columns,
          and the stiffness and driving speed recorded in its `info`;
        - `mass`: the slider's mass $m$ (kg);
        - `stiffness`: the spring's $k$ (N/m; default: the one the extraction used);
        - `v_b`: the driving speed $V$ (m/s; default: the sticks' measured loading slope,
          `info["v_b_estimated"]`, else the given `info["v_b"]`);
        - `zeta`: the viscous damping $c/(m\omega_0)$ assumed (default $10^{-3}$: negligible;
          the models need it above 0).

        The static friction is the median peak force and the kinetic friction $F_s$ less
        half the median force drop (a noise-free undamped slip drops the force by
        $2(F_s - F_k)$): they set the length unit $x_0$, so that a fitted threshold
        `x0` near 1 is the median cycle. The slider has no noise: its noise and the
        model's natural frequency are what a fit estimates.

        **Returns:** a `Slider`. A missing column or setting raises a `ParameterError`.
        """
        owner = "Slider.from_cycles"
        table = getattr(cycles, "table", None)
        info = getattr(cycles, "info", None)
        if not isinstance(table, dict) or not isinstance(info, dict):
            raise ParameterError(owner, "cycles", "must be the Cycles of extract_cycles")
        for name in ("peak_force", "force_drop"):
            if name not in table:
                raise ParameterError(
                    owner, f"cycles.{name}", "is missing: extract the cycles from a force trace "
                    "(extract_cycles(t, force=F, stiffness=k) or stickslip cycles --force-column)",
                )  # fmt: skip
        if stiffness is None:
            stiffness = info.get("stiffness")
            if stiffness is None:
                raise ParameterError(owner, "stiffness", "is required: cycles.info has none")
        if v_b is None:
            v_b = info.get("v_b_estimated") or info.get("v_b")
            if v_b is None:
                raise ParameterError(owner, "v_b", "is required: cycles.info has none")
        mass = check_positive(owner, "mass", mass)
        stiffness = check_positive(owner, "stiffness", stiffness)
        zeta = check_positive(owner, "zeta", zeta)
        peak = np.asarray(table["peak_force"], float)
        drop = np.asarray(table["force_drop"], float)
        ok = np.isfinite(peak) & np.isfinite(drop)
        if not ok.any():
            raise ParameterError(owner, "cycles", "has no cycle with a finite peak force and drop")
        static = float(np.median(peak[ok]))
        omega0 = math.sqrt(stiffness / mass)
        return cls(
            mass=mass, stiffness=stiffness, v_b=float(v_b), static_friction=static,
            kinetic_friction=static - 0.5 * float(np.median(drop[ok])),
            damping=zeta * mass * omega0,
        )  # fmt: skip

    def si_table(self, result) -> list[dict[str, Any]]:
        r"""A fit's free parameters in SI, with their 95 % intervals: one row per quantity,
        each a monotone function of one fitted parameter in this slider's units (so its
        interval's ends map to the quantity's).

        **Arguments:**

        - `result`: a `FitResult` of a model fitted in this slider's units (`fit(...,
          scales=slider)`, or data from `to_model`).

        **Returns:** a list of dicts with `quantity`, `unit`, `parameter` (the fitted one),
        `estimate`, `low` and `high` (nan where the fit gave no interval). The rows:
        `omega0` as the natural frequency $\omega_0\sqrt{k/m}$ (rad/s), the effective
        mass $m/\omega_0^2$ (kg) and the half period (s); `D` as the acceleration noise's intensity
        $S/m_{eff}^2 = \hat D\,\omega_0^3 x_0^2$ (m²/s³, the friction noise over the
        effective mass), and as $S$ (N² s) when `omega0` is not fitted; `x0` and a
        threshold law's entries as forces above the sliding friction $F_k + cV$ (N, a
        spread as a force); `zeta` as $c/m_{eff}$ (1/s), `tau` in s, `v_b` in m/s.
        """
        s = self.scales
        estimate = getattr(result, "estimate", None)
        ci = getattr(result, "ci", None)
        if not isinstance(estimate, dict) or not isinstance(ci, dict):
            raise ParameterError("Slider.si_table", "result", "must be a FitResult (from fit)")
        rows: list[dict[str, Any]] = []

        def add(quantity, unit, name, fn, spread=False):
            if name not in estimate:
                return
            lo, hi = (float(x) for x in ci.get(name, (math.nan, math.nan)))
            if spread and math.isfinite(lo):
                lo = max(lo, 0.0)  # a spread's interval stops at 0
            low = high = math.nan
            if math.isfinite(lo) and math.isfinite(hi) and (spread or name == "x0" or lo > 0):
                low, high = sorted((fn(lo), fn(hi)))
            rows.append(dict(quantity=quantity, unit=unit, parameter=name,
                             estimate=fn(float(estimate[name])), low=low, high=high))  # fmt: skip

        add("natural frequency omega_eff", "rad/s", "omega0", lambda w: w * s.omega0)
        add("effective mass k / omega_eff^2", "kg", "omega0", lambda w: self.mass / w**2)
        add("half period pi / omega_eff", "s", "omega0", lambda w: math.pi / (w * s.omega0))
        if "omega0" in estimate:
            add("noise intensity S / m_eff^2", "m^2/s^3", "D",
                lambda d: d * s.omega0**3 * s.length**2)  # fmt: skip
        else:
            add("noise intensity S", "N^2 s", "D", lambda d: d * s.noise)
        add("static - sliding friction F_s - F_k - c V", "N", "x0", lambda x: x * s.force)
        for entry, what in (("mean", "mean of"), ("low", "lowest"), ("high", "highest")):
            add(f"{what} F_s - F_k - c V", "N", f"threshold_params.{entry}",
                lambda x: x * s.force)  # fmt: skip
        add("sd of the static friction F_s", "N", "threshold_params.sd",
            lambda x: x * s.force, spread=True)  # fmt: skip
        add("damping rate c / m_eff", "1/s", "zeta", lambda z: z * s.omega0)
        add("noise correlation time tau_c", "s", "tau", lambda t: t * s.time)
        add("driving speed V", "m/s", "v_b", lambda v: v * s.velocity)
        return rows

    # -- conversions -----------------------------------------------------------------------
    def seconds(self, t):
        """Model times (units of $1/\\omega_0$) in seconds."""
        return np.asarray(t, float) * self.scales.time

    def metres(self, x):
        """Model lengths (units of $x_0$: spring extension) in metres."""
        return np.asarray(x, float) * self.scales.length

    def newtons(self, dx):
        """Model position *differences* (a slip distance $d$) as spring-force differences in
        newtons: $k x_0 d$ (a force drop)."""
        return np.asarray(dx, float) * self.scales.force

    def force(self, x):
        """The spring force (N) at model position $x$: $F_k + cV + k x_0 x$ (the threshold
        $x_0$ gives the static friction)."""
        s = self.scales
        return s.force_offset + np.asarray(x, float) * s.force

    def to_si(self, ensemble) -> SliderCycles:
        """An `Ensemble` simulated from `model()` as per-cycle SI results (`SliderCycles`)."""
        from ._simulate import Ensemble

        if not isinstance(ensemble, Ensemble):
            raise ParameterError("Slider.to_si", "ensemble", "must be an Ensemble from simulate")
        self._check_same_model(ensemble.info.get("params", {}))
        s = self.scales
        x0 = np.asarray(ensemble.onset_state, float)[:, 0]
        d = np.asarray(ensemble.slip_distance, float)
        t_sl = np.asarray(ensemble.slip_time, float)
        model_units = {
            "slip_time": t_sl,
            "slip_distance": d,
            "stick_time": np.asarray(ensemble.stick_time, float),
            "period": np.asarray(ensemble.period, float),
            "peak_force": x0,
            "force_drop": d,
            "slider_travel": d + ensemble.info["params"]["v_b"] * t_sl,
        }
        table = {}
        for name, values in model_units.items():
            table[name] = self.force(values) if name == "peak_force" else self._si(name, values)
        info = dict(
            slider=self.si_dict(),
            model=self.model_name,
            params=self.dimensionless(),
            dt=ensemble.info.get("dt", float("nan")) * s.time,
            t_max=ensemble.info.get("t_max", float("nan")) * s.time,
            dt_model=ensemble.info.get("dt"),
            t_max_model=ensemble.info.get("t_max"),
            seed=ensemble.info.get("seed"),
            units="time in s, lengths in m, forces in N",
        )
        return SliderCycles(table, {k: quantity(k).unit for k in table}, info, ensemble)

    def _factor(self, name) -> float:
        """The SI value of the model's unit of the per-cycle quantity `name`."""
        s = self.scales
        return {"time": s.time, "length": s.length, "force": s.force}[quantity(name).dimension]

    def _si(self, name, values):
        return np.asarray(values, float) * self._factor(name)

    def _check_same_model(self, params):
        mine = self.dimensionless()
        for key, value in mine.items():
            theirs = params.get(key)
            if key == "threshold_params":
                same = isinstance(theirs, dict) and all(
                    math.isclose(theirs.get(k, math.nan), v, rel_tol=1e-12, abs_tol=1e-300)
                    for k, v in value.items()
                )
            elif isinstance(value, float):
                same = isinstance(theirs, (int, float)) and math.isclose(
                    float(theirs), value, rel_tol=1e-12, abs_tol=1e-300
                )
            else:
                same = theirs == value
            if not same:
                raise ParameterError(
                    "Slider.to_si", "ensemble", f"was simulated from another model ({key} = "
                    f"{theirs!r}, this slider's is {value!r})",
                )  # fmt: skip

    def to_model(self, cycles):
        """Per-cycle SI values (a dict of arrays, or the `Cycles` of `extract_cycles` on a
        force trace) in this slider's model units, e.g. for `stickslip.fit`.

        Times are multiplied by $\\omega_0$, `slip_distance` divided by $x_0$,
        `force_drop` by $k x_0$ (it becomes the model's $d$), `peak_force` becomes the
        threshold $(F - F_k - cV)/(k x_0)$. A `Cycles` comes back as a `Cycles` whose
        `info` has the sampling interval and v_b in model units and the original settings
        under `info["si"]`. Columns of unknown unit raise a `ParameterError`."""
        s = self.scales
        table = getattr(cycles, "table", cycles)
        if not isinstance(table, dict):
            raise ParameterError(
                "Slider.to_model", "cycles", "must be a dict of per-cycle arrays or a Cycles"
            )
        out = {}
        for name, values in table.items():
            values = np.asarray(values, float)
            if name in ("release_time", "slip_time", "stick_time", "period"):
                out[name] = values * s.omega0
            elif name == "slip_distance":
                out[name] = values / s.length
            elif name == "force_drop":
                out[name] = values / s.force
            elif name == "peak_force":
                out[name] = (values - s.force_offset) / s.force
            else:
                raise ParameterError(
                    "Slider.to_model", f"cycles.{name}", "is a column of unknown unit (known: "
                    "release_time, slip_time, stick_time, period in s, slip_distance in m, "
                    "force_drop, peak_force in N)",
                )  # fmt: skip
        info = getattr(cycles, "info", None)
        if info is None:
            return out
        new_info = {"units": f"model units of {self!r}", "si": dict(info)}
        if "sampling_interval" in info:
            new_info["sampling_interval"] = float(info["sampling_interval"]) * s.omega0
        if info.get("v_b") is not None:
            new_info["v_b"] = float(info["v_b"]) / s.velocity
        return type(cycles)(out, new_info)

    # -- results ---------------------------------------------------------------------------
    def _noise_free_slip(self) -> tuple[float, float]:
        """(T_sl, d) of the noise-free slip in model units: closed form (see module docs)."""
        p = self.dimensionless()
        return noise_free_slip(p["zeta"], p["v_b"])

    def deterministic(self) -> SliderCycles:
        r"""The noise-free cycle in SI (one row), in closed form: with $\zeta = 0$,
        $\omega_0 T_{sl} = 2\pi - 2\arctan(\omega_0 x_0 / V)$ and a force drop of exactly
        $2(F_s - F_k)$; with $0 < \zeta < 2$ the first return of
        $v(t) = e^{-\zeta t/2}(V\cos\omega_d t - C\sin\omega_d t)$ to $V$, found by Brent's
        method between the minimum of $v$ and its next maximum (inf if that maximum stays
        below $V$: steady sliding). With a random threshold, the cycle at the law's centre."""
        t_sl, d = self._noise_free_slip()
        v_b = self.dimensionless()["v_b"]
        model_units = {
            "slip_time": t_sl,
            "slip_distance": d,
            "stick_time": d / v_b,
            "period": t_sl + d / v_b,
            "force_drop": d,
            "slider_travel": d + v_b * t_sl,
        }
        table = {k: np.atleast_1d(self._si(k, v)) for k, v in model_units.items()}
        table["peak_force"] = np.atleast_1d(self.force(1.0))
        table = {k: table[k] for k in COLUMNS}
        info = dict(slider=self.si_dict(), params=self.dimensionless(), noise_free=True)
        return SliderCycles(table, {k: quantity(k).unit for k in table}, info)

    def simulate(self, n_paths: int, dt: float | None = None, t_max: float | None = None,
                 seed: int = 0, **kwargs) -> SliderCycles:  # fmt: skip
        """`stickslip.simulate` of `model()`, one cycle per path, in SI.

        `dt` and `t_max` in seconds (defaults: 0.02/omega0 and 100/omega0; a `dt` above
        1/omega0 raises a `ParameterError`: the slip lasts about pi/omega0). Other keyword
        arguments go to `simulate` as they are.

        **Returns:** `SliderCycles`.
        """
        from ._simulate import simulate

        s = self.scales
        owner = "Slider.simulate"
        dt_model = DEFAULT_STEP if dt is None else check_positive(owner, "dt", dt) * s.omega0
        if dt_model > MAX_STEP:
            raise ParameterError(
                owner, "dt", f"is {dt_model:.3g} times 1/omega0 = {s.time:.4g} s, above "
                f"{MAX_STEP:g}: a slip lasts about pi/omega0 (is dt in seconds?)", dt,
            )  # fmt: skip
        if t_max is None:
            t_max_model = DEFAULT_HORIZON
        else:
            t_max_model = check_positive(owner, "t_max", t_max) * s.omega0
        ens = simulate(self.model(), n_paths, dt_model, t_max_model, seed, **kwargs)
        return self.to_si(ens)

    def density(self, kind: str, values, *, estimator=None, **kwargs):
        """A crossing-estimator density in SI: `kind` = `"slip_time"` (per second, at times
        in s), `"period"` (per second), `"slip_distance"` (per metre, at distances in m) or
        `"force_drop"` (per newton, at drops in N). `estimator`: a `CrossingEstimator` of
        `model()` to reuse (default: a new one); other keyword arguments (`method`,
        `order`, ...) go to the estimator's density. Period and distance values must be
        evenly spaced (cell averages, as in the estimator)."""
        from ._estimate import CrossingEstimator

        # (a force drop is k times the slip distance: the same density in other units)
        method = {
            "slip_time": "slip_time_density",
            "period": "period_density",
            "slip_distance": "slip_distance_density",
            "force_drop": "slip_distance_density",
        }
        if kind not in method:
            raise ParameterError(
                "Slider.density", "kind", f"must be one of {', '.join(map(repr, method))}",
                kind,
            )  # fmt: skip
        if estimator is None:
            estimator = CrossingEstimator(self.model())
        unit = self._factor(kind)
        x = np.asarray(values, float) / unit
        return np.asarray(getattr(estimator, method[kind])(x, **kwargs)) / unit

    # -- display ---------------------------------------------------------------------------
    def si_dict(self) -> dict[str, Any]:
        """The slider's SI fields as a plain dict."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}

    def describe(self) -> str:
        """A table of the slider, its scales and the model's dimensionless parameters, with
        the formulas, and the noise-free cycle."""
        s = self.scales
        p = self.dimensionless()
        rows = [("slider (SI)", "", "")]
        rows += [
            ("m", f"{self.mass:.6g} kg", "mass"),
            ("k", f"{self.stiffness:.6g} N/m", "spring stiffness"),
            ("V", f"{self.v_b:.6g} m/s", "driving speed"),
        ]
        if self.threshold is None:
            rows.append(("F_s", f"{self.static_friction:.6g} N", "static friction"))
        else:
            law, q = self.threshold
            args = ", ".join(f"{k}={v:.6g}" for k, v in q.items())
            rows.append(("F_s", f"{law}({args}) N", "static friction, drawn per cycle"))
        rows += [
            ("F_k", f"{self.kinetic_friction:.6g} N", "kinetic friction"),
            ("c", f"{self.damping:.6g} kg/s", "viscous damping"),
            ("S", f"{self.noise:.6g} N^2 s", "friction-noise intensity"),
            ("tau_c", "-" if self.noise_time is None else f"{self.noise_time:.6g} s",
             "noise correlation time"),
            ("scales", "", ""),
            ("omega0", f"{s.omega0:.6g} rad/s", "sqrt(k/m)"),
            ("time unit", f"{s.time:.6g} s", "1/omega0"),
            ("length unit x0", f"{s.length:.6g} m", "(F_s - F_k - c V)/k"),
            ("velocity unit", f"{s.velocity:.6g} m/s", "omega0 x0"),
            ("force unit", f"{s.force:.6g} N", "k x0"),
            ("noise unit", f"{s.noise:.6g} N^2 s", "m^2 omega0^3 x0^2"),
            (f"model '{self.model_name}'", "", ""),
            ("omega0", "1", "(time unit)"),
            ("zeta", f"{p['zeta']:.6g}", "c/(m omega0)"),
            ("v_b", f"{p['v_b']:.6g}", "V/(omega0 x0)"),
            ("D", f"{p['D']:.6g}", "S/(m^2 omega0^3 x0^2)"),
            ("tau", "None" if p["tau"] is None else f"{p['tau']:.6g}", "omega0 tau_c"),
        ]  # fmt: skip
        if self.threshold is None:
            rows.append(("x0", "1", "(length unit)"))
        else:
            args = ", ".join(f"{k}={v:.6g}" for k, v in p["threshold_params"].items())
            rows.append(("threshold", f"{p['threshold']}({args})", "(F - F_k - c V)/(k x0)"))
        t_sl, d = self._noise_free_slip()
        rows.append(("noise-free cycle", "", ""))
        if math.isfinite(t_sl):
            rows += [
                ("T_sl", f"{t_sl * s.time:.6g} s", f"omega0 T_sl = {t_sl:.6g}"),
                ("force drop", f"{d * s.force:.6g} N", f"d = {d:.6g} x0"),
                ("T_st", f"{d * s.length / self.v_b:.6g} s", "(force drop)/(k V)"),
            ]
        else:
            rows.append(("T_sl", "inf", "steady sliding: no stick-slip without noise"))
        width = max(len(r[0]) for r in rows) + 2
        vwidth = max(len(r[1]) for r in rows) + 2
        lines = []
        for name, value, formula in rows:
            if not value and not formula:
                lines.append(f"{name}:")
            else:
                lines.append(f"  {name:<{width}}{value:<{vwidth}}{formula}".rstrip())
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.describe()


def noise_free_slip(zeta: float, v_b: float) -> tuple[float, float]:
    r"""The noise-free slip of eq. (8) from $(x, v) = (1, v_b)$ with $\omega_0 = 1$:
    `(T_sl, d)`, the first $t > 0$ with $v(t) = v_b$ and $d = 1 - x(T_{sl})$.

    $\zeta = 0$: $T_{sl} = 2\pi - 2\arctan(1/v_b)$, $d = 2$ (energy: $x_{sl} = -x_0$).
    $0 < \zeta < 2$: $v(t) = e^{-\gamma t}(v_b\cos\omega_d t - C\sin\omega_d t)$ with
    $\gamma = \zeta/2$, $\omega_d = \sqrt{1 - \gamma^2}$, $C = (\gamma v_b + 1)/\omega_d$;
    writing $v = R e^{-\gamma t}\cos(\omega_d t + \varphi)$, $\tan\varphi = C/v_b$, its
    extrema are at $\omega_d t + \varphi = j\pi - \psi$, $\tan\psi = \gamma/\omega_d$: the
    return lies between the first minimum and the next maximum, or never comes (inf, inf).
    $\zeta \ge 2$: $v$ relaxes to 0 without coming back (inf, inf)."""
    from scipy import optimize

    if zeta == 0.0:
        t = 2.0 * math.pi - 2.0 * math.atan2(1.0, v_b)
        return t, 2.0
    if zeta >= 2.0:
        return math.inf, math.inf
    g = 0.5 * zeta
    wd = math.sqrt((1.0 - g) * (1.0 + g))
    C = (g * v_b + 1.0) / wd
    phi, psi = math.atan2(C, v_b), math.atan2(g, wd)
    t_min = (math.pi - psi - phi) / wd
    t_max = (2.0 * math.pi - psi - phi) / wd

    def excess(t):
        return math.exp(-g * t) * (v_b * math.cos(wd * t) - C * math.sin(wd * t)) - v_b

    top = excess(t_max)
    if top < 0:
        return math.inf, math.inf
    t = t_max if top == 0 else optimize.brentq(excess, t_min, t_max, xtol=1e-15, rtol=1e-15)
    x = math.exp(-g * t) * (math.cos(wd * t) + (v_b + g) / wd * math.sin(wd * t))
    return t, 1.0 - x
