"""stickslip: statistics of frictional stick-slip motion.

`import stickslip` is light: JAX, diffrax and equinox load on first use of a name that needs
them (a model class, the simulator, the estimator).
"""

from importlib import import_module as _import_module
from importlib.metadata import PackageNotFoundError as _PNF
from importlib.metadata import version as _version

from ._errors import DataError as DataError
from ._errors import OutputError as OutputError
from ._errors import ParameterError as ParameterError
from ._errors import PluginError as PluginError
from ._errors import ResourceError as ResourceError
from ._errors import StickSlipError as StickSlipError
from ._registry import get_model as get_model
from ._registry import list_models as list_models
from ._registry import refresh_models as refresh_models
from ._registry import register_model as register_model

try:
    __version__ = _version("stickslip")
except _PNF:  # running from a source tree that is not installed
    __version__ = "0+unknown"

# name -> module that defines it; loaded on first access (PEP 562).
_LAZY = {
    "FrictionModel": "._model",
    "LinearGaussian": "._model",
    "simulate": "._simulate",
    "simulate_cycles": "._simulate",
    "simulate_chain": "._simulate",
    "ChainModel": "._model",
    "CreepingSlider": "._model",
    "ChainRun": "._simulate",
    "Ensemble": "._simulate",
    "CycleSeries": "._simulate",
    "Upcrossings": "._simulate",
    "ExactGaussian": "._solver",
    "CrossingEstimator": "._estimate",
    "FrictionLaw": ".friction",
    "get_friction_law": ".friction",
    "ApproximationWarning": "._estimate",
    "EulerMaruyama": "._solver",
    "Study": ".study",
    "StudyError": ".study",
    "load_study": ".study",
    "run_study": ".study",
    "deterministic_slip": ".stability",
    "critical_speed": ".stability",
    "stability_report": ".stability",
    "StabilityReport": ".stability",
    "select_method": ".selection",
    "first_passage_density": ".selection",
    "MethodChoice": ".selection",
    "SelectionError": ".selection",
    "SelectionWarning": ".selection",
    "fit": "._inference.fit",
    "FitResult": "._inference.result",
    "load_fit": "._inference.loaded",
    "Prediction": "._inference.predict",
    "goodness_of_fit": "._inference.goodness",
    "GoodnessOfFit": "._inference.goodness",
    "compare_fits": "._inference.compare",
    "Comparison": "._inference.compare",
    "draw_replicates": "._inference.compare",
    "Replicates": "._inference.compare",
    "Measurement": "._inference.measurement",
    "Statistic": "._inference.statistics",
    "AndersonDarling": "._inference.statistics",
    "CramerVonMises": "._inference.statistics",
    "KolmogorovSmirnov": "._inference.statistics",
    "clear_caches": "._compile",
    "cache_info": "._compile",
    "extract_cycles": ".extract",
    "read_cycles": ".extract",
    "Cycles": ".extract",
    "analyse_run": ".extract",
    "Run": ".extract",
    "TraceKind": ".trace_kinds",
    "get_trace_kind": ".trace_kinds",
    "list_trace_kinds": ".trace_kinds",
    "register_trace_kind": ".trace_kinds",
    "Campaign": ".study.campaign",
    "Slider": ".units",
    "SliderCycles": ".units",
}

__all__ = [
    "DataError",
    "OutputError",
    "ParameterError",
    "ResourceError",
    "PluginError",
    "StickSlipError",
    "get_model",
    "list_models",
    "refresh_models",
    "register_model",
    "__version__",
    *_LAZY,
]


def __getattr__(name):
    if name in _LAZY:
        value = getattr(_import_module(_LAZY[name], __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'stickslip' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY))
