"""Fitting the mission surrogates (:class:`~ovtraj.pipeline.features.MissionSurrogates`) on
a run's training data: the wait model on H_P0, the models the settings add (the pass
model of T_total, the closed-form burn phase, the phasing wait of the known limits), then
the phase-input model on the design and the phase (docs/optimize.md).
"""

from __future__ import annotations

from concurrent.futures import Executor
from typing import Any

import numpy as np

from ovtraj.config import Scenario
from ovtraj.launch.fourier import FourierSeries
from ovtraj.launch.launch_fit import find_launch_fit
from ovtraj.mission import DESIGN_NAMES
from ovtraj.pipeline.burn_phase import BurnPhaseModel
from ovtraj.pipeline.features import (
    DEORBIT_WAIT,
    DV_PARTS,
    PAYLOAD,
    PHASING_WAIT,
    WAIT,
    DvFloors,
    KnownLimits,
    MissionSurrogates,
    composed_waits,
    target_draconic_period,
)
from ovtraj.pipeline.pass_model import PassModel
from ovtraj.surrogate import SurrogateError, SurrogateSet, fit_surrogates
from ovtraj.surrogate.validation import holdout_mask
from ovtraj.units import S_PER_HOUR

__all__ = ["fit_mission_surrogates", "launch_payload", "pinned_deorbit_burns"]


def fit_mission_surrogates(
    data: Any,
    scenario: Scenario,
    lower: np.ndarray,
    upper: np.ndarray,
    *,
    candidates: dict[str, str] | None = None,
    executor: Executor | None = None,
) -> MissionSurrogates:
    """Fit the wait model and the phase-input model on a run's training data.

    ``candidates``: an earlier fit's ``selected``, to refit those models without comparing
    candidates again; ``executor``: where the candidates are scored
    (:func:`ovtraj.surrogate.fit_surrogates`).
    """
    if not data.feasible.any():
        raise SurrogateError(f"all {len(data)} samples are infeasible: nothing to fit")
    payload = launch_payload(scenario, data)
    wait = np.asarray(data.components[WAIT], dtype=float)
    fit = (lower, upper), candidates, executor
    wait_set = _wait_fit(
        data, scenario, WAIT, np.isfinite(wait), "the phase input needs the rendezvous wait", *fit
    )
    pass_model, burn_phase = _phase_models(scenario, data, wait_set)
    bounds = _composition(scenario, payload, pass_model, burn_phase)
    if bounds["limits"] is not None:
        # the samples whose rendezvous got as far as a refined phasing wait (feasible ones,
        # and those refused by less than the burn window: both sides of the limit); further
        # beyond, the stage kept a secular estimate only, and those samples stay out
        phasing = np.asarray(data.components[PHASING_WAIT], dtype=float)
        rendezvous = scenario.rendezvous
        longest = rendezvous.max_wait_time_s + rendezvous.burn_epoch_window_s
        usable = np.isfinite(phasing) & (phasing <= longest)
        needs = "the wait limit needs the phasing wait"
        bounds["phasing"] = _wait_fit(data, scenario, PHASING_WAIT, usable, needs, *fit)
    period = target_draconic_period(scenario)
    composed = MissionSurrogates(wait_set, None, period, lower, upper, **bounds)
    main = _main_set(data, scenario, composed, lower, upper, candidates, executor)
    return MissionSurrogates(wait_set, main, period, lower, upper, **bounds)


def _first_per_parking_altitude(data: Any, known: np.ndarray) -> np.ndarray:
    """``known`` (n,) bool, keeping the first sample of each distinct H_P0 alone: the
    waits depend on H_P0 alone (infill points at a bound share it, and repeated inputs
    make Kriging's correlation matrix singular)."""
    _, first = np.unique(data.designs[:, 0], return_index=True)
    return known & np.isin(np.arange(len(known)), first)


def _wait_fit(
    data: Any,
    scenario: Scenario,
    name: str,
    usable: np.ndarray,
    needs: str,
    bounds: tuple[np.ndarray, np.ndarray],
    candidates: dict[str, str] | None,
    executor: Executor | None,
) -> SurrogateSet:
    """The set of the wait ``name`` [s] on H_P0, fitted on the ``usable`` samples (the
    first of each H_P0; each one counted feasible: only its value is modelled); ``needs``
    begins the refusal of too few samples (what needs which wait)."""
    settings = scenario.mission.surrogate
    known = _first_per_parking_altitude(data, usable)
    if known.sum() < settings.min_training_samples:
        raise SurrogateError(
            f"{needs} of at least "
            f"{settings.min_training_samples} samples; {int(known.sum())} have one"
        )
    lower, upper = bounds
    return fit_surrogates(
        data.designs[known][:, :1],
        {name: np.asarray(data.components[name], dtype=float)[known]},
        np.ones(int(known.sum()), dtype=bool),
        lower[:1],
        upper[:1],
        settings,
        input_names=DESIGN_NAMES[:1],
        sample_ids=data.sample_ids[known],
        candidates=candidates,
        executor=executor,
    )


def _phase_models(
    scenario: Scenario, data: Any, wait_set: SurrogateSet
) -> tuple[PassModel | None, BurnPhaseModel | None]:
    """The closed-form models the settings ask for: the pass model of T_total
    (``pass_forecast``, calibrated on the run's T_total with the wait model's waits) and
    the burn phase (``burn_phase``)."""
    settings = scenario.mission.surrogate
    pass_model = None
    if settings.pass_forecast is not None:
        series = find_launch_fit(scenario).series
        pass_model = PassModel.of(scenario, series["insertion_time_s"], series["flight_time_s"])
        pass_model = pass_model.calibrated(
            data.designs, composed_waits(wait_set, data.designs), data.outputs["t_total_s"]
        )
    burn_phase = None
    if settings.burn_phase:
        series = find_launch_fit(scenario).series
        burn_phase = BurnPhaseModel.of(
            scenario, series["insertion_time_s"], series["insertion_u_deg"]
        )
    return pass_model, burn_phase


def _composition(
    scenario: Scenario,
    payload: FourierSeries,
    pass_model: PassModel | None,
    burn_phase: BurnPhaseModel | None,
) -> dict[str, Any]:
    """The keyword arguments of :class:`MissionSurrogates` besides its fitted sets."""
    settings = scenario.mission.surrogate
    return {
        "payload": payload,
        "floors": DvFloors.of(scenario),
        "stay_s": S_PER_HOUR * scenario.mission.stay_h,
        "softness_s": S_PER_HOUR * settings.floor_softness_h,
        "softness_mps": settings.floor_softness_mps,
        "pass_model": pass_model,
        "burn_phase": burn_phase,
        "departure_phase": settings.departure_phase,
        "limits": KnownLimits.of(scenario, pass_model),
    }


def _main_set(
    data: Any,
    scenario: Scenario,
    composed: MissionSurrogates,
    lower: np.ndarray,
    upper: np.ndarray,
    candidates: dict[str, str] | None,
    executor: Executor | None,
) -> SurrogateSet:
    """The phase-input model: the dV parts (and T_total without the pass model) and the
    feasibility classifier, on the design and ``composed``'s phase inputs."""
    settings = scenario.mission.surrogate
    # The samples a known limit made infeasible say nothing of the other causes the
    # classifier is left to learn.
    classified = None
    if composed.limits is not None:
        classified = ~composed.limits.explained(data, composed.pass_model)
    time = {} if composed.pass_model is not None else {"t_total_s": data.outputs["t_total_s"]}
    outputs = {
        **time,
        **{name: np.where(data.feasible, data.components[name], np.nan) for name in DV_PARTS},
    }
    return fit_surrogates(
        composed.features(data.designs),
        outputs,
        data.feasible,
        np.concatenate([lower, [-1.0] * len(composed.phase_inputs)]),
        np.concatenate([upper, [1.0] * len(composed.phase_inputs)]),
        settings,
        input_names=(*DESIGN_NAMES, *composed.phase_inputs),
        sample_ids=data.sample_ids,
        candidates=candidates,
        executor=executor,
        output_inputs={k: v for k, v in settings.part_inputs.items() if k in outputs},
        left_out=_pinned_deorbit_burns(data, settings),
        classified=classified,
    )


def launch_payload(scenario: Scenario, data: Any) -> FourierSeries:
    """The launch fit's payload series, checked against the run's own M_load values."""
    fit = find_launch_fit(scenario)
    if fit is None:
        raise SurrogateError(
            "no launch fit is stored for this scenario: M_load is the launch fit's payload "
            "(ovtraj launch-fit solves it)"
        )
    payload = fit.series[PAYLOAD]
    known = np.isfinite(data.outputs["m_load_kg"])
    if known.any():
        expected = np.asarray(payload(data.designs[known, 0] * 1e3), dtype=float)
        tolerance = scenario.mission.surrogate.payload_match_kg
        worst = float(np.max(np.abs(expected - data.outputs["m_load_kg"][known])))
        if worst > tolerance:
            raise SurrogateError(
                f"the stored launch fit's payload differs from the run's M_load by up to "
                f"{worst:.3g} kg (surrogate.payload_match_kg {tolerance:g} kg): the run was "
                "evaluated with another launch fit"
            )
    return payload


def pinned_deorbit_burns(data: Any) -> np.ndarray:
    """The feasible samples whose deorbit burn the stage's correction pinned at the start
    of the preparation orbit (its burn-time bound; the stage's ``wait_time_s`` is 0): a
    pass reached only by moving the burn, at a cost in impulse (the 7 costliest deorbits,
    91-172 m/s, of the direct method's 583 feasible designs; every other one 71-88 m/s;
    docs/optimize.md)."""
    wait = np.asarray(data.components[DEORBIT_WAIT], dtype=float)
    return data.feasible & ~(wait > 0.0)


def _pinned_deorbit_burns(data: Any, settings: Any) -> dict[str, np.ndarray]:
    """``left_out`` of the phase-input model: the deorbit part's regime is the minimum
    impulse after a wait (``surrogate.skip_pinned_deorbit_burns``), so the pinned burns
    stay out of its fit when enough samples remain."""
    if not settings.skip_pinned_deorbit_burns:
        return {}
    pinned = pinned_deorbit_burns(data)
    # The training samples fit_surrogates would keep (its seeded hold-out split).
    held = holdout_mask(data.feasible, settings.holdout_fraction, settings.seed)
    if not pinned.any() or (data.feasible & ~held & ~pinned).sum() < (
        settings.min_training_samples
    ):
        return {}
    return {"dv_deorbit_mps": pinned}
