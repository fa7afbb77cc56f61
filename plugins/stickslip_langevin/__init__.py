"""The Langevin sliding-friction model of the paper (eqs. 8-9), as a stickslip plugin."""

from ._model import Langevin as Langevin
from ._model import LangevinSlip as LangevinSlip

__all__ = ["Langevin", "LangevinSlip"]
