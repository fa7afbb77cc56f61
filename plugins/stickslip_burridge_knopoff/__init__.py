"""The Burridge-Knopoff chain with friction noise, as a stickslip plugin."""

from ._model import BurridgeKnopoff as BurridgeKnopoff

__all__ = ["BurridgeKnopoff"]
