"""Entry-state prediction from osculating elements (seed 004, sec. 2.3) and the cut-off
tests: a kernel shared by the seed-004 study (:mod:`ovtraj.studies.deorbit_burn`) and the
mission's closed-loop Monte Carlo (:mod:`ovtraj.mission.montecarlo`), hence in ``astro``.

During the burn, as soon as the osculating perigee is below the entry radius, the entry
point that a cut-off *now* would give is predicted from the current osculating elements:

1. osculating -> mean elements, first-order J2 short-period terms removed (seed eqs. 12-13
   and 14-20, here Brouwer's terms in Lyddane's nonsingular form, exact in e, which the
   seed truncates to first order in e: :func:`ovtraj.astro.j2_elements.osculating_to_mean`);
2. time to go Delta t to the entry, from the mean argument-of-latitude rate (seed eq. 23);
3. the mean elements drift over Delta t by the J2 secular rates of raan, argp and
   lambda = M + argp (seed eqs. 21-22 and 24; :func:`ovtraj.astro.j2_elements.propagate_mean`;
   with J2 alone the long-period terms are O(J2 e), metres here, see that module);
4. the short-period terms at the predicted entry position are added back (seed eqs. 14-19,
   :func:`ovtraj.astro.j2_elements.mean_to_osculating`), giving the osculating a, e, argp
   at the entry (eq. 25);
5. the osculating conic crosses r_E at the true anomaly f_E (descending branch, seed eq. 26):
   cos f_E = (p / r_E - 1) / e, f_E in (pi, 2 pi); u_E = argp + f_E, the flight-path angle
   tan gamma_E = e sin f_E / (1 + e cos f_E) (eq. 3) and the speed
   v_E = sqrt(mu (2 / r_E - 1 / a)) (vis-viva);
6. Delta t is corrected by the angle between u_E and the predicted position's u divided by
   the angular rate h / r^2, and steps 3-5 repeated (``iterations`` passes).

Every function is vectorised over states: the cut-off search predicts a whole grid of burn
instants in one call. SI units throughout (m, m/s, rad, s).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ovtraj.astro.angles import TWO_PI, wrap_to_pi, wrap_to_two_pi
from ovtraj.astro.constants import EarthConstants
from ovtraj.astro.elements import (
    eccentricity_vector_from_dots,
    perigee_radius_from_semi_latus_rectum,
    rv_to_nonsingular,
    true_to_mean_argument_of_latitude,
)
from ovtraj.astro.j2_elements import (
    mean_to_osculating,
    osculating_to_mean,
    propagate_mean,
    secular_rates,
)

__all__ = ["EntryPrediction", "cutoff_margin", "predict_entry", "state_perigee_radius"]


@dataclass(frozen=True)
class EntryPrediction:
    """Predicted entry state for each input state (NaN where the orbit misses r_E).

    u_rad is unwrapped to lie ahead of the current argument of latitude; fpa_rad < 0;
    speed_mps inertial; time_to_go_s from the input state's instant.
    """

    u_rad: NDArray[np.float64]
    fpa_rad: NDArray[np.float64]
    speed_mps: NDArray[np.float64]
    time_to_go_s: NDArray[np.float64]


def state_perigee_radius(
    r: NDArray[np.float64], v: NDArray[np.float64], mu: float
) -> NDArray[np.float64]:
    """Osculating perigee radius p / (1 + e) [m] of states r [m], v [m/s] shaped (n, 3)."""
    r_norm = np.linalg.norm(r, axis=-1)
    v_sq = np.einsum("...k,...k->...", v, v)
    r_dot_v = np.einsum("...k,...k->...", r, v)
    ecc = eccentricity_vector_from_dots(
        r, v, r_norm[..., None], v_sq[..., None], r_dot_v[..., None], mu
    )
    e = np.linalg.norm(ecc, axis=-1)
    h_sq = r_norm**2 * v_sq - r_dot_v**2
    return perigee_radius_from_semi_latus_rectum(h_sq / mu, e)


def _conic_entry(
    a: NDArray[np.float64],
    ex: NDArray[np.float64],
    ey: NDArray[np.float64],
    entry_radius: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """argp + f_E and gamma_E of the conic's descending crossing of r_E (seed eqs. 25-26, 3)."""
    e = np.hypot(ex, ey)
    p = a * (1.0 - e * e)
    with np.errstate(divide="ignore", invalid="ignore"):
        cos_f = (p / entry_radius - 1.0) / e
    cos_f = np.where(np.abs(cos_f) <= 1.0, cos_f, np.nan)
    f = TWO_PI - np.arccos(cos_f)
    fpa = np.arctan2(e * np.sin(f), 1.0 + e * cos_f)
    return np.arctan2(ey, ex) + f, fpa


def predict_entry(
    r: NDArray[np.float64],
    v: NDArray[np.float64],
    *,
    earth: EarthConstants,
    entry_radius: float,
    iterations: int,
) -> EntryPrediction:
    """Predict the entry (u, gamma, speed, time to go) of coasting from states r, v (n, 3).

    See the module notes for the steps and the seed equations. ``earth.j2 == 0`` gives the
    two-body prediction (the conic through the current state). entry_radius [m].
    """
    mu, radius, j2 = earth.mu, earth.radius, earth.j2
    r = np.atleast_2d(np.asarray(r, dtype=float))
    v = np.atleast_2d(np.asarray(v, dtype=float))
    osc = rv_to_nonsingular(r, v, mu=mu)
    u_now = np.asarray(osc.u, dtype=float)
    mean = osc if j2 == 0.0 else osculating_to_mean(osc, mu=mu, radius=radius, j2=j2)
    m_a, m_ex, m_ey, m_i = (np.asarray(x, dtype=float) for x in (mean.a, mean.ex, mean.ey, mean.i))
    _, argp_dot, mean_anomaly_dot = secular_rates(
        m_a, np.hypot(m_ex, m_ey), m_i, mu=mu, radius=radius, j2=j2
    )
    lam_rate = np.asarray(mean_anomaly_dot) + np.asarray(argp_dot)

    # First guess: the osculating conic through the current state (two-body).
    u_entry, _ = _conic_entry(
        np.asarray(osc.a), np.asarray(osc.ex), np.asarray(osc.ey), entry_radius
    )
    u_entry = u_now + wrap_to_two_pi(u_entry - u_now)
    lam_now = np.asarray(true_to_mean_argument_of_latitude(np.asarray(mean.u), m_ex, m_ey))
    lam_entry = np.asarray(true_to_mean_argument_of_latitude(u_entry, m_ex, m_ey))
    # Time to go (seed eq. 23): the mean-latitude angle still to fly over its secular rate.
    dt = (wrap_to_two_pi(lam_entry - lam_now + 0.1) - 0.1) / lam_rate
    # States whose orbit misses r_E are carried along with dt = 0 and reported as NaN
    # (Kepler's equation must not see a NaN).
    reaches = np.isfinite(dt)

    fpa = speed = np.full_like(u_now, np.nan)
    for _ in range(iterations):
        dt = np.where(reaches, dt, 0.0)
        at_entry = propagate_mean(mean, dt, mu=mu, radius=radius, j2=j2)
        if j2 != 0.0:
            at_entry = mean_to_osculating(at_entry, mu=mu, radius=radius, j2=j2)
        a, ex, ey = (np.asarray(x, dtype=float) for x in (at_entry.a, at_entry.ex, at_entry.ey))
        u_pred = np.asarray(at_entry.u, dtype=float)
        u_conic, fpa = _conic_entry(a, ex, ey, entry_radius)
        offset = wrap_to_pi(u_conic - u_pred)
        p = a * (1.0 - ex * ex - ey * ey)
        r_pred = p / (1.0 + ex * np.cos(u_pred) + ey * np.sin(u_pred))
        u_rate = np.sqrt(mu * p) / r_pred**2
        u_entry = u_now + wrap_to_two_pi(u_pred - u_now) + offset
        speed = np.sqrt(mu * (2.0 / entry_radius - 1.0 / a))
        dt = dt + offset / u_rate
        reaches &= np.isfinite(dt)
    nan = np.nan
    return EntryPrediction(
        u_rad=np.where(reaches, u_entry, nan),
        fpa_rad=np.where(reaches, fpa, nan),
        speed_mps=np.where(reaches, speed, nan),
        time_to_go_s=np.where(reaches, dt, nan),
    )


def cutoff_margin(
    prediction: EntryPrediction, strategy: int, target_u: float, target_fpa: float
) -> NDArray[np.float64]:
    """The cut-off function: positive while the engine must keep burning, <= 0 to cut.

    Strategy 1 (seed sec. 3): predicted entry u minus the target u_E [rad], wrapped to
    (-pi, pi] (the predicted entry point moves up-range as the burn goes on). Strategy 2:
    predicted entry flight-path angle minus gamma_E [rad] (it steepens). NaN predictions (the
    orbit does not reach r_E yet) give +inf.
    """
    if strategy == 1:
        margin = wrap_to_pi(prediction.u_rad - target_u)
    elif strategy == 2:
        margin = prediction.fpa_rad - target_fpa
    else:
        raise ValueError(f"strategy must be 1 or 2, got {strategy}")
    return np.where(np.isfinite(margin), margin, np.inf)
