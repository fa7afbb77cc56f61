"""The event-driven stick/slip simulator."""

from .driver import simulate as simulate
from .ensemble import Ensemble as Ensemble
