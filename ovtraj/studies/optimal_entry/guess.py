"""The initial guess: one entry flown with constant controls, so the user never gives one.

The vehicle flies the configured bank and either the configured angle of attack or the
one of maximum lift-to-drag ratio at the initial Mach number (inside the alpha bounds):
the best glide, a natural first shape for a range objective and a harmless one for the
others (Betts, *Practical Methods for Optimal Control*, 2nd ed., 2010, sec. 4.8, on
guesses from simulation). The flight stops at the terminal energy (see
:func:`target_energy`), on the ground, or at the time limit. Terminal conditions other
than the energy are not met by the guess; the NLP reaches them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.polynomial import polynomial as npoly
from numpy.typing import NDArray

from ovtraj.deadline import Deadline
from ovtraj.studies.optimal_entry.flight import fly
from ovtraj.studies.optimal_entry.flight_kernel import ControlTable
from ovtraj.studies.optimal_entry.problem import EntryProblem

__all__ = ["GuessTrajectory", "best_glide_alpha", "guess_trajectory", "target_energy"]


@dataclass(frozen=True)
class GuessTrajectory:
    """Times [s], states (rows of h, lon, lat, V, gamma, psi) and the constant controls."""

    t: NDArray[np.float64]
    y: NDArray[np.float64]
    alpha: float
    bank: float
    target_energy: float
    status: str


def target_energy(problem: EntryProblem) -> float:
    """The terminal energy the guess flies to [J/kg]: the fixed one, or the middle of its range.

    Capped below the initial energy (the problem's check guarantees the range starts there).
    """
    e0 = problem.initial_energy
    e_lo, e_hi = problem.terminal_energy_bounds()
    e_hi = min(e_hi, e0)
    return 0.5 * (e_lo + e_hi)


def best_glide_alpha(problem: EntryProblem) -> float:
    """Angle of attack [rad] of maximum L/D at the initial Mach number, inside its bounds."""
    h0, v0 = problem.initial_state[0], problem.initial_state[3]
    z = min(max(h0, 0.0), problem.atmosphere_top_m)
    mach = v0 / float(problem.atmosphere.speed_of_sound(z))
    grid = np.linspace(
        problem.control_lower[0],
        problem.control_upper[0],
        problem.config.guess.alpha_grid_points,
    )
    a = grid * problem.alpha_scale
    cl = npoly.polyval2d(a, np.full_like(a, mach), problem.cl)
    cd = npoly.polyval2d(a, np.full_like(a, mach), problem.cd)
    ratio = np.where(cd > 0.0, cl / np.where(cd > 0.0, cd, 1.0), -np.inf)
    return float(grid[int(np.argmax(ratio))])


def guess_trajectory(problem: EntryProblem, deadline: Deadline | None = None) -> GuessTrajectory:
    """The guess flight; at ``deadline`` it stops where it is (status ``time limit``)."""
    g = problem.config.guess
    alpha = math.radians(g.alpha_deg) if g.alpha_deg is not None else best_glide_alpha(problem)
    bank = math.radians(g.bank_deg)
    target = target_energy(problem)
    flown = fly(
        problem,
        ControlTable.constant(alpha, bank),
        g.max_time_s,
        rtol=g.relative_tolerance,
        atol=g.relative_tolerance,
        stop_energy=target,
        deadline=deadline,
    )
    return GuessTrajectory(
        t=flown.t,
        y=flown.y,
        alpha=alpha,
        bank=bank,
        target_energy=target,
        status=flown.status,
    )
