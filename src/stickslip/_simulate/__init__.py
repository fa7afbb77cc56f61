"""The event-driven stick/slip simulator."""

from .._model import ChainModel as ChainModel
from .chain import ChainRun as ChainRun
from .chain import simulate_chain as simulate_chain
from .cycles import CycleSeries as CycleSeries
from .cycles import simulate_cycles as simulate_cycles
from .driver import simulate as simulate
from .ensemble import Ensemble as Ensemble
from .upcrossings import Upcrossings as Upcrossings
