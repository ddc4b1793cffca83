"""Outer multi-objective optimisation of the mission (SPEC step 5; docs/optimize.md).

``objectives``: the mission objectives and their normalisation; ``front``: Pareto
filtering and the hypervolume; ``nsga2``: NSGA-II (pymoo) on any vectorised model,
and on a :class:`~ovtraj.surrogate.SurrogateSet`; ``infill``: which front points to
verify with the real chain.
"""

from ovtraj.optimize.front import hypervolume, non_dominated
from ovtraj.optimize.infill import hypervolume_picks, spread_picks
from ovtraj.optimize.nsga2 import SurrogateFront, nsga2_front, surrogate_front
from ovtraj.optimize.objectives import MISSION_OBJECTIVES, Normalisation, Objective

__all__ = [
    "MISSION_OBJECTIVES",
    "Normalisation",
    "Objective",
    "SurrogateFront",
    "hypervolume",
    "hypervolume_picks",
    "non_dominated",
    "nsga2_front",
    "spread_picks",
    "surrogate_front",
]
