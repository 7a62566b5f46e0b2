"""Problems as modules: what a case's ``analysis = "NAME"`` selects, found by name in a
registry.

A problem (:class:`ProblemKind`) brings the metrics that compare a run with its theory or
reference, its figures, the columns it adds to the printed summary and to the sweep and paper
tables, its sweep criterion and the paper's figures.  The built-in ones are the paper's three
examples (section 5), one module each:

- ``bars`` (:mod:`.bars`): Example 1, two elastic bars in collinear impact (section 5.1);
- ``taylor`` (:mod:`.taylor`): Example 2, the Taylor bar on a rigid wall (section 5.2);
- ``cantilever`` (:mod:`.cantilever`): Example 3, the Parkes cantilever (section 5.3);
- ``perforation`` (:mod:`.perforation`): a projectile into a plate (residual velocity, hole);
- ``plates`` (:mod:`.plates`): symmetric plate impact in uniaxial strain against the exact
  elastic precursor and plastic shock;
- ``rings`` (:mod:`.rings`): two elastic rubber rings in collision (Gray, Monaghan & Swift
  2001): rebound, tears and clumps;

and ``none``, no problem-specific analysis (the default).

Adding a problem, from user code or in this package::

    from impactsph.problems import GeometryNeeds, ProblemKind, register_problem

    @register_problem
    class Toy(ProblemKind):
        name = "toy"
        geometry_needs = GeometryNeeds(bodies=1, types=("block",))

        def metrics(self, sim):
            return {"max_displacement": ...}

        def summary_keys(self, case):
            return ("max_displacement",)

after which a case file may say ``analysis = "toy"``.  The registry is per process: a case
file that lists the module under ``plugins`` has it imported wherever the case is validated,
in the worker processes of a sweep (``impactsph sweep``, :func:`impactsph.sweep.run_many`)
too; a problem registered by a script's own code alone is unknown to those workers.
"""

from __future__ import annotations

from .bars import BarsProblem
from .base import GeometryNeeds, ProblemKind, SweepCriterion
from .cantilever import CantileverProblem
from .perforation import PerforationProblem
from .plates import PlatesProblem
from .registry import (
    NoAnalysis,
    analyse,
    get_problem,
    problem_names,
    register_problem,
    unregister_problem,
)
from .rings import RingsProblem
from .taylor import TaylorProblem

__all__ = ["GeometryNeeds", "ProblemKind", "SweepCriterion", "analyse", "get_problem",
           "problem_names", "register_problem", "unregister_problem"]

for _kind in (NoAnalysis, BarsProblem, TaylorProblem, CantileverProblem, PerforationProblem,
              PlatesProblem, RingsProblem):
    register_problem(_kind)
