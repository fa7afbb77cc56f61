"""The Langevin sliding-friction model of the paper (eqs. 8-9), as a stickslip plugin."""

from ._model import Langevin as Langevin
from ._model import LangevinSlip as LangevinSlip
from ._scales import check_noise as check_noise
from ._scales import check_rate as check_rate
from ._scales import check_speed as check_speed

__all__ = ["Langevin", "LangevinSlip", "check_noise", "check_rate", "check_speed"]
