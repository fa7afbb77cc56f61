"""The Langevin model with a random static threshold, as a stickslip plugin."""

from ._laws import THRESHOLD_LAWS as THRESHOLD_LAWS
from ._laws import ThresholdLaw as ThresholdLaw
from ._laws import check_spread as check_spread
from ._laws import make_law as make_law
from ._model import HeldRandomThreshold as HeldRandomThreshold
from ._model import RandomThreshold as RandomThreshold

__all__ = [
    "RandomThreshold",
    "HeldRandomThreshold",
    "ThresholdLaw",
    "THRESHOLD_LAWS",
    "make_law",
    "check_spread",
]
