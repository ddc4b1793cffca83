"""The launch aimed at the target's plane at the rendezvous, not at insertion.

The launch stage times the drop so that the parking orbit's mean node is the target's at
insertion (patent step 101). At a lower altitude, J2 regresses the parking orbit's node
faster than the target's (Vallado, 4th ed., eq. 9-41: dOmega/dt = -3/2 n J2 (R/p)^2 cos i),
~0.35 deg/day on the default scenario, so after a 31-45 h phasing wait the two planes are
0.44-0.45 deg apart and the rendezvous pays for it with cross-track impulses wherever the
phasing puts its burns (a median 1.66x its Hohmann cost, docs/rendezvous.md).

An air launch chooses its drop time freely, and the ascent relative to the Earth does not
depend on it: a drop ``dt`` later turns the insertion orbit's node ``(omega_E -
dOmega_T/dt) dt`` east relative to the target's. Aiming the node
``dOmega = (dOmega_T/dt - dOmega_P/dt) t_aim`` east of the target's, with ``t_aim`` the
time from insertion to the middle of the rendezvous transfer, puts the two planes together
there (the residual at either burn is the transfer orbit's own differential regression
over half a transfer, ~0.003 deg). The wait depends on the insertion time (the target
moves on while the drop waits), so the node, the insertion time and the wait are iterated
to a fixed point; the wait moves ~1.1 h per 0.45 deg of node, so each iteration shrinks
the change ~30-fold.

The wait is the rendezvous stage's own first estimate (J2 secular rates,
:func:`ovtraj.rendezvous.phasing.secular_phasing`): the stage then refines it by a few
minutes on the propagated phase, which moves the aimed node by ~1e-3 deg.

Where the wait's first opportunity wraps (the target's lead at insertion one synodic
revolution from the burn's), the iteration may have no fixed point: a later insertion
puts the burn a synodic period later, and an earlier one makes it the next pass. The
iterate whose planes are the closest at the predicted transfer is kept, and
``converged`` is False.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from numpy.typing import NDArray

from ovtraj.astro.constants import EarthModel
from ovtraj.astro.elements import FloatOrArray, NonsingularElements
from ovtraj.astro.j2_elements import secular_rates
from ovtraj.config.mission import PlaneAimSettings
from ovtraj.rendezvous.phasing import secular_phasing

__all__ = ["AimedInsertion", "aim_insertion", "aimed_node_offset", "drop_delay_s", "nodal_rate"]


def nodal_rate(mean: NonsingularElements, earth: EarthModel) -> float:
    """Secular rate of the node [rad/s] of mean elements under J2 (Vallado eq. 9-41)."""
    e = math.hypot(float(mean.ex), float(mean.ey))
    rate, _, _ = secular_rates(
        float(mean.a), e, float(mean.i), mu=earth.mu, radius=earth.radius, j2=earth.j2
    )
    return float(rate)


def aimed_node_offset(
    drift_rad_s: FloatOrArray, wait_s: FloatOrArray, transfer_time_s: FloatOrArray
) -> FloatOrArray:
    """Node [rad] east of the target's that puts the planes together at the middle of the
    transfer: ``drift (wait + T_H / 2)``, ``drift = dOmega_T/dt - dOmega_P/dt`` [rad/s],
    the wait and the Hohmann time in s (module notes; floats or arrays)."""
    return drift_rad_s * (wait_s + 0.5 * transfer_time_s)


def drop_delay_s(
    raan_offset_rad: FloatOrArray, omega_earth_rad_s: float, target_raan_rate_rad_s: float
) -> FloatOrArray:
    """How much later [s] the drop (and the insertion) comes for the node ``raan_offset_rad``
    east of the target's: the Earth turns the launch's plane at ``omega_E - dOmega_T/dt``
    relative to the target's (module notes; floats or arrays)."""
    return raan_offset_rad / (omega_earth_rad_s - target_raan_rate_rad_s)


@dataclass(frozen=True)
class AimedInsertion:
    """The insertion aimed at the target's plane at the rendezvous transfer.

    ``raan_offset_rad``: the parking orbit's mean node east of the target's at insertion;
    ``insertion_time_s`` [s from the launch day's 0 h] and ``state`` (ECI, m and m/s);
    ``wait_s``: the predicted phasing wait; ``plane_difference_rad``: the predicted angle
    between the planes at the middle of the transfer (the fixed point's residual in node,
    times sin i: planes of equal inclination whose nodes differ by a small dOmega);
    ``iterations``, ``converged`` (module notes)."""

    raan_offset_rad: float
    insertion_time_s: float
    state: NDArray
    wait_s: float
    plane_difference_rad: float
    iterations: int
    converged: bool


def aim_insertion(
    insertion_at: Callable[[float], tuple[float, NDArray, NonsingularElements]],
    target_at: Callable[[float], NDArray],
    earth: EarthModel,
    settings: PlaneAimSettings,
) -> AimedInsertion:
    """Iterate node -> insertion -> wait -> node (module notes).

    ``insertion_at(raan_offset_rad) -> (t_ins, state, mean)``: the insertion whose mean node
    is that far east of the target's, and its mean elements; ``target_at(t) -> state``: the
    target's ECI state. The map is nearly linear (slope ~0.03), so after two plain steps
    each next offset is the secant's root of ``aimed(offset) - offset``; a secant step that
    does not reduce the residual is replaced by a plain one.
    """
    tolerance = math.radians(settings.tolerance_deg)  # on the node
    best: AimedInsertion | None = None
    history: list[tuple[float, float]] = []  # (offset, aimed - offset)
    offset = 0.0
    for iteration in range(1, settings.max_iterations + 1):
        t_ins, state, mean = insertion_at(offset)
        phasing = secular_phasing(state, target_at(t_ins), earth, mean_chaser=mean)
        if not math.isfinite(phasing.wait_s):  # equal periods: nothing drifts apart
            t0, state0, _ = insertion_at(0.0)
            return AimedInsertion(0.0, t0, state0, math.inf, 0.0, iteration, False)
        drift = nodal_rate(phasing.mean_target, earth) - nodal_rate(mean, earth)
        aimed = aimed_node_offset(drift, phasing.wait_s, phasing.transfer.transfer_time_s)
        residual = aimed - offset
        candidate = AimedInsertion(
            offset,
            t_ins,
            state,
            phasing.wait_s,
            abs(math.sin(float(phasing.mean_target.i)) * residual),
            iteration,
            abs(residual) <= tolerance,
        )
        improved = best is None or candidate.plane_difference_rad < best.plane_difference_rad
        if improved:
            best = candidate
        if candidate.converged:
            return candidate
        history.append((offset, residual))
        offset = aimed
        if len(history) >= 2 and improved:
            (x0, g0), (x1, g1) = history[-2:]
            if g1 != g0:
                offset = x1 - g1 * (x1 - x0) / (g1 - g0)
    return best
