"""impactsph: smoothed particle hydrodynamics for solids under impact.

Python API::

    from impactsph import load_case, Simulation, run_case
    case = load_case("bars", ["viscosity.alpha1=0.3"])
    summary = run_case(case, "runs/bars")       # everything, outputs and figures
    sim = Simulation(case); sim.run(t_end=5e-6)  # or step by step, state in sim.state
"""

from ._version import __version__
from .config import Case, CaseError, load_case
from .runner import run_case
from .simulation import Simulation, SimulationError

__all__ = ["Case", "CaseError", "Simulation", "SimulationError", "__version__", "load_case",
           "run_case"]
