"""dampersim: simulation and analysis of two-stage arc-spring torque converter dampers.

The model follows the PhD thesis "The Simulation and Experimental Characterisation of
the Torque Converter Damper System" (University of Bath, 2017), cited in the code as
``[thesis]``. The pipeline is

    parameters -> excitation -> solver kernel -> SimulationResult -> analysis -> plotting

and the public entry points are re-exported here.
"""

from dampersim.version import __version__  # noqa: E402,F401

from dampersim.errors import DampersimError, ParameterError, SimulationDiverged  # noqa: E402
from dampersim.parameters import DamperSystem, default_parameters, load_parameters  # noqa: E402
from dampersim.excitation import OrderSum, TorqueRamp, MeasuredTorque  # noqa: E402
from dampersim.simulation import simulate  # noqa: E402
from dampersim.results import SimulationResult  # noqa: E402

__all__ = [
    "__version__",
    "DampersimError",
    "ParameterError",
    "SimulationDiverged",
    "DamperSystem",
    "default_parameters",
    "load_parameters",
    "OrderSum",
    "TorqueRamp",
    "MeasuredTorque",
    "simulate",
    "SimulationResult",
]
