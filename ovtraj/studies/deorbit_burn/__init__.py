"""Finite-thrust deorbit burn by osculating-element prediction (seed 004).

Entry requirements become transfer-orbit requirements; a mean-element two-orbit intersection
gives the impulsive burn start, size and angle; the burn is propagated under J2 with constant
thrust and the engine cut when the entry state predicted from the osculating elements meets
its target (strategy 1: argument of latitude, strategy 2: flight-path angle); the burn start
is iterated by u_open <- u_open - k_u (u - u_E). Also a burn-angle study and a seeded Monte
Carlo of the closed-loop burn. Problems are posed by YAML
(``configs/cases/shuttle_deorbit.yaml`` is the seed's published case). See
``docs/deorbit_burn.md``.
"""

from ovtraj.studies.deorbit_burn.iteration import IterationRecord
from ovtraj.studies.deorbit_burn.montecarlo import (
    SIMULATIONS,
    MonteCarloContext,
    monte_carlo_summary,
    run_monte_carlo,
)
from ovtraj.studies.deorbit_burn.problem import (
    DeorbitBurnProblem,
    deorbit_burn_from_dict,
    load_deorbit_burn,
)
from ovtraj.studies.deorbit_burn.published import (
    Comparison,
    format_comparison,
    published_comparison,
)
from ovtraj.studies.deorbit_burn.report import deorbit_burn_report, format_report
from ovtraj.studies.deorbit_burn.result import DeorbitBurnResult
from ovtraj.studies.deorbit_burn.solve import solve_deorbit_burn
from ovtraj.studies.deorbit_burn.study import burn_angle_study, zero_speed_error_angles

__all__ = [
    "SIMULATIONS",
    "Comparison",
    "DeorbitBurnProblem",
    "DeorbitBurnResult",
    "IterationRecord",
    "MonteCarloContext",
    "burn_angle_study",
    "deorbit_burn_from_dict",
    "deorbit_burn_report",
    "format_comparison",
    "format_report",
    "load_deorbit_burn",
    "monte_carlo_summary",
    "published_comparison",
    "run_monte_carlo",
    "solve_deorbit_burn",
    "zero_speed_error_angles",
]
