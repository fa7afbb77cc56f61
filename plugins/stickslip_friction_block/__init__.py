"""A block on a moving belt with a nonlinear friction law: a model plugin written the way a
user would write one (see docs/extending.md)."""

from ._model import FrictionBlock as FrictionBlock

__all__ = ["FrictionBlock"]
