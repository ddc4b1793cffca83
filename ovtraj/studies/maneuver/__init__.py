"""Quick orbit manoeuvre of an upper stage (seed 003).

Minimum-time (or minimum-dv) multi-impulse interception, rendezvous or orbit transfer
under the stage's delta-v budget: the seed's improved differential evolution (or
scipy's) over impulse vectors and epochs with the last leg solved exactly (Lambert),
then the finite-thrust correction (eq. 15 burns re-optimised by SLSQP with the mass
flow integrated). Problems are posed by YAML (``configs/cases/upper_stage_rendezvous.yaml``
is the seed's published case). See ``docs/maneuver.md``.
"""

from ovtraj.astro.rocket import burn_duration, dv_budget_seed, rocket_capacity
from ovtraj.studies.maneuver.problem import ManeuverProblem, load_maneuver, maneuver_from_dict
from ovtraj.studies.maneuver.result import BurnReport, ManeuverResult, comparison_rows
from ovtraj.studies.maneuver.solve import search_impulses, solve_maneuver

__all__ = [
    "BurnReport",
    "ManeuverProblem",
    "ManeuverResult",
    "burn_duration",
    "comparison_rows",
    "dv_budget_seed",
    "load_maneuver",
    "maneuver_from_dict",
    "rocket_capacity",
    "search_impulses",
    "solve_maneuver",
]
