"""Rate-and-state friction (Dieterich-Ruina) on a spring-driven slider: a model plugin
written against stickslip's public surface, as a third party would write one."""

from ._model import RateAndState as RateAndState

__all__ = ["RateAndState"]
