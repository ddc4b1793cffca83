"""The project's mean elements of an element set: a least-squares fit to its SGP4 ephemeris.

SGP4's mean elements (Brouwer/Kozai, WGS-72, with drag, J3, J4 and deep-space
terms) are not the project's: those are first-order J2 Brouwer mean elements
(``ovtraj.astro.j2_elements``) whose state the J2 propagator flies. So the
project's orbit of an element set is the initial state x0 at the epoch that,
flown by :class:`~ovtraj.astro.propagation.OrbitPropagator` (point mass + J2,
heyoka), best matches SGP4's positions over ``fit_span_h`` from the epoch,
sampled every ``fit_step_s``:

    min over x0 of  sum_k |r_J2(t_k; x0) - r_SGP4(t_k)|^2

by ``scipy.optimize.least_squares`` (trust-region reflective), started at SGP4's
own state at the epoch. The unknowns are the offsets of x0 from that start scaled
by |r0| and |v0| (dimensionless, so position and velocity weigh alike), and the
Jacobian is taken by forward differences with a relative step sqrt(tol) of the
integrator's tolerance tol (the step that balances truncation against the
propagation's own error; Nocedal & Wright 2006, sec. 8.1). The mean elements are
``state_to_mean(x0)``, whose ``mean_to_state`` gives x0 back to rounding, so the
fit is equally a fit of the mean elements. What the fit cannot absorb (drag, the
J2^2/J4 secular and J3 long-period terms, lunisolar terms of deep-space orbits) is
its residual, reported as the rms and maximum position error over the span
(``docs/targets.md`` lists measured figures).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from ovtraj.astro.angles import wrap_to_two_pi
from ovtraj.astro.constants import EarthModel
from ovtraj.astro.elements import (
    NonsingularElements,
    nonsingular_to_classical,
    true_to_mean_anomaly,
)
from ovtraj.astro.epoch import Epoch
from ovtraj.astro.j2_elements import state_to_mean
from ovtraj.astro.propagation import OrbitPropagator
from ovtraj.config.target import TargetSourceSettings
from ovtraj.deadline import Deadline
from ovtraj.element_sets.elements import SourceElements
from ovtraj.element_sets.ephemeris import sgp4_eci
from ovtraj.errors import ConfigError
from ovtraj.units import M_PER_KM, S_PER_DAY, S_PER_HOUR

__all__ = ["PoorTargetFitWarning", "StaleElementSetWarning", "TargetFit", "fit_target"]

_SETTINGS = "target.source_settings"


class StaleElementSetWarning(UserWarning):
    """The element set's epoch lies farther from the fit epoch than ``max_age_days``."""


class PoorTargetFitWarning(UserWarning):
    """The J2 orbit misses SGP4 by more than ``fit_warning_km`` somewhere in the span."""


@dataclass(frozen=True)
class TargetFit:
    """The fitted orbit of an element set at ``epoch`` and how well it matches SGP4."""

    source: SourceElements
    epoch: Epoch
    state: np.ndarray  # ECI (m, m/s) at the epoch, the J2 propagator's initial state
    mean: NonsingularElements  # first-order J2 mean elements of ``state``
    mean_anomaly_rad: float
    span_s: float
    samples: int
    rms_error_m: float
    max_error_m: float
    evaluations: int
    converged: bool
    reason: str | None

    @property
    def source_age_days(self) -> float:
        """Days from the element set's epoch to the fit epoch (negative: fit before it)."""
        return self.epoch.seconds_since(self.source.epoch) / S_PER_DAY

    def to_row(self) -> dict[str, Any]:
        """The report: mean elements at the epoch, fit errors, the source and its age."""
        coe = nonsingular_to_classical(self.mean)
        return {
            "epoch_utc": self.epoch.iso(),
            "semi_major_axis_km": float(coe.a) / M_PER_KM,
            "eccentricity": float(coe.e),
            "inclination_deg": math.degrees(float(coe.i)),
            "raan_deg": math.degrees(float(coe.raan)),
            "arg_perigee_deg": math.degrees(float(coe.argp)),
            "mean_anomaly_deg": math.degrees(self.mean_anomaly_rad),
            "true_anomaly_deg": math.degrees(float(coe.nu)),
            "element_set": "mean",
            "rms_error_km": self.rms_error_m / M_PER_KM,
            "max_error_km": self.max_error_m / M_PER_KM,
            "span_h": self.span_s / S_PER_HOUR,
            "samples": self.samples,
            "evaluations": self.evaluations,
            "converged": self.converged,
            "reason": self.reason,
            "object_name": self.source.name,
            "catalog_number": self.source.catalog_number,
            "source_format": self.source.kind,
            "source_epoch_utc": self.source.epoch.iso(),
            "source_age_days": self.source_age_days,
        }


def _sample_times(span_s: float, step_s: float) -> np.ndarray:
    t = np.arange(math.floor(span_s / step_s) + 1, dtype=float) * step_s
    return t if math.isclose(t[-1], span_s) else np.append(t, span_s)


def fit_target(
    source: SourceElements,
    epoch: Epoch,
    *,
    earth: EarthModel,
    tol: float,
    settings: TargetSourceSettings,
) -> TargetFit:
    """Fit the project's J2 orbit at ``epoch`` to ``source``'s SGP4 ephemeris (module notes).

    ``tol`` is the Taylor integrator's tolerance (the scenario's
    ``tolerances.integrator``). Warns (:class:`StaleElementSetWarning`,
    :class:`PoorTargetFitWarning`) but never refuses an old element set or a poor
    fit; raises :class:`ConfigError` when SGP4 cannot reach the span. A fit stopped
    by ``fit_max_iterations`` or ``fit_time_limit_s`` is returned unconverged with the
    limit in ``reason``.
    """
    _warn_if_stale(source, epoch, settings)
    span_s = settings.fit_span_h * S_PER_HOUR
    t = _sample_times(span_s, settings.fit_step_s)
    r_ref, v_ref = sgp4_eci(source, epoch, t, omega=earth.omega)
    positions = _FittedPositions(source, r_ref, v_ref, t, OrbitPropagator(earth, tol=tol))
    deadline = Deadline(settings.fit_time_limit_s, f"{_SETTINGS}.fit_time_limit_s")
    solution = least_squares(
        positions.residuals,
        np.zeros(6),
        method="trf",
        diff_step=math.sqrt(tol),
        max_nfev=settings.fit_max_iterations,
        callback=lambda intermediate_result: deadline.stop_if_expired(),
    )
    reason = None
    if deadline.reached:
        reason = deadline.reason(int(solution.nfev), "evaluations")
    elif solution.status == 0:
        reason = f"{_SETTINGS}.fit_max_iterations = {settings.fit_max_iterations} reached"
    state = positions.state(solution.x)
    errors = np.linalg.norm(positions(solution.x) - r_ref, axis=1)
    mean = state_to_mean(state[:3], state[3:], mu=earth.mu, radius=earth.radius, j2=earth.j2)
    coe = nonsingular_to_classical(mean)
    fit = TargetFit(
        source=source,
        epoch=epoch,
        state=state,
        mean=mean,
        mean_anomaly_rad=wrap_to_two_pi(float(true_to_mean_anomaly(coe.nu, coe.e))),
        span_s=span_s,
        samples=len(t),
        rms_error_m=float(np.sqrt(np.mean(errors**2))),
        max_error_m=float(errors.max()),
        evaluations=int(solution.nfev),
        converged=reason is None,
        reason=reason,
    )
    _warn_if_poor(fit, settings)
    return fit


class _FittedPositions:
    """The J2 positions [m] at the sample times ``t`` [s] of the state ``start + z * scale``,
    ``start`` SGP4's state at the epoch and ``scale`` (|r0|, |v0|) (module notes), and
    their residuals from SGP4's positions ``r_ref``."""

    def __init__(
        self,
        source: SourceElements,
        r_ref: np.ndarray,
        v_ref: np.ndarray,
        t: np.ndarray,
        propagator: OrbitPropagator,
    ) -> None:
        self.source = source
        self.r_ref = r_ref
        self.t = t
        self.start = np.r_[r_ref[0], v_ref[0]]
        self.r_scale = float(np.linalg.norm(r_ref[0]))
        self.scale = np.r_[np.full(3, self.r_scale), np.full(3, np.linalg.norm(v_ref[0]))]
        self.propagator = propagator  # compiled once per thread and tolerance

    def state(self, z: np.ndarray) -> np.ndarray:
        return self.start + z * self.scale

    def __call__(self, z: np.ndarray) -> np.ndarray:
        try:
            return self.propagator.propagate_grid(self.state(z), 0.0, self.t)[:, :3]
        except RuntimeError as err:
            raise ConfigError([f"the fit to SGP4 of {self.source.label()} failed: {err}"]) from None

    def residuals(self, z: np.ndarray) -> np.ndarray:
        return ((self(z) - self.r_ref) / self.r_scale).ravel()


def _warn_if_stale(source: SourceElements, epoch: Epoch, settings: TargetSourceSettings) -> None:
    """Warn (at :func:`fit_target`'s caller) when the element set's epoch lies more than
    ``max_age_days`` from the fit epoch."""
    age_days = epoch.seconds_since(source.epoch) / S_PER_DAY
    if abs(age_days) > settings.max_age_days:
        warnings.warn(
            StaleElementSetWarning(
                f"stale element set: {source.label()} of {source.epoch.iso()} is "
                f"{abs(age_days):.1f} days from the epoch {epoch.iso()} "
                f"({_SETTINGS}.max_age_days = {settings.max_age_days:g})"
            ),
            stacklevel=3,
        )


def _warn_if_poor(fit: TargetFit, settings: TargetSourceSettings) -> None:
    """Warn (at :func:`fit_target`'s caller) when the fit misses SGP4 by more than
    ``fit_warning_km`` somewhere in the span."""
    if fit.max_error_m > settings.fit_warning_km * M_PER_KM:
        warnings.warn(
            PoorTargetFitWarning(
                f"poor fit: the J2 orbit misses SGP4 of {fit.source.label()} by up to "
                f"{fit.max_error_m / M_PER_KM:.1f} km over {fit.span_s / S_PER_HOUR:g} h "
                f"({_SETTINGS}.fit_warning_km = {settings.fit_warning_km:g}); drag dominated?"
            ),
            stacklevel=3,
        )
