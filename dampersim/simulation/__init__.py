"""Runs of the models: the damper driven by an excitation, and the pulsation generator.

:mod:`.damper` holds :func:`simulate` (parameters + excitation -> SimulationResult);
:mod:`.pulsation` the pulsation generator runs, alone or driving the damper. Both go
through :mod:`dampersim.solver.driver`.
"""

from dampersim.simulation.damper import natural_duration, simulate
from dampersim.simulation.pulsation import (
    PulsationResult,
    dominant_order_over_speed,
    pulsation_excitation,
    simulate_pulsation,
)
from dampersim.solver.driver import ensure_compiled

__all__ = [
    "simulate",
    "natural_duration",
    "ensure_compiled",
    "PulsationResult",
    "simulate_pulsation",
    "pulsation_excitation",
    "dominant_order_over_speed",
]
