"""Slip-phase solvers (diffrax solvers over an ensemble state)."""

from .base import AbstractSlipSolver as AbstractSlipSolver
from .base import PathwiseBrownian as PathwiseBrownian
from .base import SlipTerm as SlipTerm
from .euler import EulerMaruyama as EulerMaruyama
from .exact import ExactGaussian as ExactGaussian
