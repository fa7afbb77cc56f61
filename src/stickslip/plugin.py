"""Everything a model plugin needs, public and stable.

A plugin (a package that registers models under the `stickslip.models` entry-point group,
as the built-in ones do) imports from here and from `stickslip` only, never from a private
module (`stickslip._...`), which may change without notice:

```python
from stickslip.plugin import FrictionModel, check_positive, jnp

class MyBlock(FrictionModel):
    ...
```

**Model base classes**

- `FrictionModel`: a single-block slip phase and its stick and release (see
  docs/extending.md); `LinearGaussian`, what `FrictionModel.linear_gaussian()` returns for a
  linear slip with additive Gaussian noise (the simulator then steps exactly and the
  estimator is exact).
- `ChainModel`: a chain of blocks that stick and slip one by one, simulated by
  `stickslip.simulate_chain`.
- `CreepingSlider`: a spring-driven slider whose friction has memory and whose velocity
  never reaches zero (rate-and-state): one motion through stick and slip, integrated
  implicitly with events at the force's peaks and troughs.

**Parameter checks.** Each returns the value as a float (or int, or the chosen string) or
raises a one-line `ParameterError` that names the owner and the parameter:
`check_real`, `check_positive`, `check_nonnegative`, `check_int`, `check_choice`; and
`build_named`, an instance of a class chosen by name from a table with its parameters (a
law of friction or of thresholds), each mistake one line naming the model's own field.

**Friction laws** (`stickslip.friction`): `FrictionLaw` (the base class of a law),
`get_friction_law`, `FRICTION_LAWS` and the built-in `Coulomb`, `LinearViscous`,
`VelocityWeakening` and `Stribeck`.

**Arrays.** `jax` and `jnp` with float64 enabled (import them from here rather than from
`jax` when a module may be imported before stickslip has set JAX up).
"""

from __future__ import annotations

from ._errors import ParameterError as ParameterError
from ._errors import PluginError as PluginError
from ._errors import build_named as build_named
from ._errors import check_choice as check_choice
from ._errors import check_int as check_int
from ._errors import check_nonnegative as check_nonnegative
from ._errors import check_positive as check_positive
from ._errors import check_real as check_real
from ._jax import jax as jax
from ._jax import jnp as jnp
from ._model import ChainModel as ChainModel
from ._model import CreepingSlider as CreepingSlider
from ._model import FrictionModel as FrictionModel
from ._model import LinearGaussian as LinearGaussian
from .friction import FRICTION_LAWS as FRICTION_LAWS
from .friction import Coulomb as Coulomb
from .friction import FrictionLaw as FrictionLaw
from .friction import LinearViscous as LinearViscous
from .friction import Stribeck as Stribeck
from .friction import VelocityWeakening as VelocityWeakening
from .friction import get_friction_law as get_friction_law

__all__ = [
    "build_named",
    "ChainModel",
    "Coulomb",
    "CreepingSlider",
    "FRICTION_LAWS",
    "FrictionLaw",
    "FrictionModel",
    "LinearGaussian",
    "LinearViscous",
    "ParameterError",
    "PluginError",
    "Stribeck",
    "VelocityWeakening",
    "check_choice",
    "check_int",
    "check_nonnegative",
    "check_positive",
    "check_real",
    "get_friction_law",
    "jax",
    "jnp",
]
