"""Settings of the whole-mission chain and its design space (SPEC step 5)."""

from __future__ import annotations

from typing import Any, Literal, get_args

from pydantic import Field, field_validator, model_validator
from pydantic_core import PydanticCustomError

from ovtraj.config.base import StrictModel, bounded
from ovtraj.config.launch import Bound
from ovtraj.config.surrogate_candidates import ClassifierName, RegressorName

# How a DoE's batches run: the one definition behind `ovtraj run --runner`, the config's
# `mission.doe.task_runner` and the flows' `runner` parameter (docs/mission.md).
# serial: one batch after another in this process (the library path of `ovtraj run`, no
# Prefect); threads / processes: Prefect task runners of this machine; dask: a Dask
# cluster (`dask_address`, or a local one of `workers` processes).
Runner = Literal["serial", "threads", "processes", "dask"]
RUNNERS: tuple[str, ...] = get_args(Runner)


class MissionBoundsConfig(StrictModel):
    """The three design variables of the whole-mission optimisation (SPEC step 5)."""

    parking_altitude_km: Bound  # H_P0, launch target (parking) altitude
    preparation_altitude_km: Bound  # H_dp, deorbit preparation orbit
    separation_delay_h: Bound  # t_dsp, after the configured stay


class BatchingSettings(StrictModel):
    """How a DoE's samples are cut into batches past ``batch_size``."""

    preferred_batch_size: int = bounded(
        ge=1, le=10000, description="samples a batch grows to in a large DoE"
    )
    batches_per_worker: int = bounded(
        ge=1, le=1000, description="batches each worker gets at least, before batches grow"
    )
    max_batches: int = bounded(
        ge=1,
        le=100000,
        description="batches of a run at most (Prefect task runs, files per store folder); "
        "past it batches grow beyond preferred_batch_size",
    )


class DoeSettings(StrictModel):
    """Design of experiments over ``mission.design_bounds`` and how the flow runs it."""

    samples: int = bounded(ge=1, le=100000)
    seed: int = bounded(ge=0, le=2**32 - 1)
    batch_size: int = bounded(ge=1, le=10000, description="samples per Prefect task")
    # Optional (null when absent: batch_size samples a batch, however many): the configs
    # stored with runs made before it existed still read.
    batching: BatchingSettings | None = Field(
        default=None,
        description="batches larger than batch_size for larger DoEs (docs/mission.md, 'Scaling')",
    )
    task_runner: Runner = Field(description="serial | threads | processes | dask (RUNNERS)")
    workers: int = bounded(ge=1, le=1024)
    dask_address: None = Field(
        default=None,
        description="always null: a scenario never names a Dask scheduler (Dask's protocol "
        "unpickles what the scheduler sends, and scenario files are shared); give it on the "
        "command line (--dask-address), as a flow parameter or in OVTRAJ_DASK_ADDRESS",
    )
    task_retries: int = bounded(ge=0, le=10)

    def batch_size_for(self, samples: int) -> int:
        """Samples a batch of a run of ``samples`` samples (``batching``: null, always
        ``batch_size``).

        A batch's files cost ~0.1 s however many samples it holds (fsync'ed Parquet
        files and a marker: 36 ms a sample in batches of 4, 6.4 ms in batches of 96,
        docs/mission.md), so a large DoE's batches grow towards ``preferred_batch_size``
        while each worker keeps ``batches_per_worker`` of them to balance the load, and
        past ``max_batches`` batches (Prefect task runs, files per folder) they grow
        further.
        """
        size = self.batch_size
        if self.batching is None:
            return size
        batching = self.batching
        balanced = -(-samples // (batching.batches_per_worker * self.workers))
        size = max(size, min(batching.preferred_batch_size, balanced))
        return max(size, -(-samples // batching.max_batches))

    @field_validator("dask_address", mode="before")
    @classmethod
    def _no_scheduler_in_a_scenario(cls, value: Any) -> Any:
        if value is not None:
            raise PydanticCustomError(
                "dask_address_in_scenario",
                "a scenario never names a Dask scheduler (Dask unpickles what it sends): "
                "give --dask-address, the flow's dask_address or OVTRAJ_DASK_ADDRESS",
            )
        return value

    store: str | None = Field(
        description="run store root, relative to the scenario file's folder; null: the "
        "workspace's runs/ (OVTRAJ_HOME, docs/mission.md)"
    )
    claim_wait_s: float = bounded(
        unit="s",
        gt=0,
        le=7 * 86400,
        description="longest wait for a batch that another process is computing",
    )


class StoreSettings(StrictModel):
    """What the run store keeps of each sample and how writers share a run."""

    orbit_trajectory_step_s: float = bounded(
        unit="s",
        gt=0,
        le=86400,
        description="stored rendezvous, transfer and deorbit tables: a row per step plus "
        "every phase's first and last",
    )
    entry_trajectory_step_s: float = bounded(
        unit="s", gt=0, le=3600, description="stored reentry table: a row per step plus the ends"
    )


DvPart = Literal["dv_rendezvous_mps", "dv_transfer_mps", "dv_deorbit_mps"]
# The phase-input model's inputs: the design, then the phase's sine and cosine (the burn's
# with burn_phase, the wait's without).
MainInput = Literal[
    "parking_altitude_km",
    "preparation_altitude_km",
    "separation_delay_h",
    "sin_2u_burn",
    "cos_2u_burn",
    "sin_wait_phase",
    "cos_wait_phase",
    "sin_departure_phase",
    "cos_departure_phase",
]
WAIT_PHASE_INPUTS = ("sin_wait_phase", "cos_wait_phase")
BURN_PHASE_INPUTS = ("sin_2u_burn", "cos_2u_burn")
DEPARTURE_PHASE_INPUTS = ("sin_departure_phase", "cos_departure_phase")


class PassForecastSettings(StrictModel):
    """The low-fidelity T_total of the phase-input surrogates (ovtraj/pipeline/pass_model.py)."""

    rendezvous_transfer_fraction: float = bounded(
        gt=0, le=10, description="the rendezvous transfer's time, in Hohmann times"
    )
    transfer_fraction: float = bounded(
        gt=0, le=10, description="the transfer to H_dp's time, in Hohmann times"
    )
    # Optional (0 when absent): the configs stored before it existed still read.
    longitude_shift_deg: float = bounded(
        unit="deg",
        ge=-10,
        le=10,
        default=0.0,
        description="added to each forecast crossing's longitude before the entry box is "
        "checked: the closed-form forecast's bias against the deorbit stage",
    )


class LargeSampleSettings(StrictModel):
    """How the surrogates are fitted on many samples: the candidates whose cost
    grows as n^2-n^3 (Kriging, RBF, the SVC and GP classifiers) on a seeded subsample, the
    cross-validation on a seeded subsample, and candidates that grow ~linearly besides."""

    exact_max_samples: int = bounded(
        ge=10,
        le=100000,
        description="KRG, KPLS, RBF, svc and gpc are fitted on at most this many of the "
        "training samples (a seeded random subsample)",
    )
    cv_max_samples: int = bounded(
        ge=10,
        le=1000000,
        description="the k-fold cross-validation runs on at most this many of the training "
        "samples (a seeded random subsample); the models kept are fitted on all of them",
    )
    extra_regressors: list[RegressorName] = Field(
        default_factory=list,
        description="candidates compared too when an output has more than exact_max_samples "
        "training samples",
    )
    gbt_iterations: int = bounded(ge=1, le=10000, description="boosting rounds of GBT")
    gbt_learning_rate: float = bounded(gt=0, le=1, description="shrinkage of GBT's rounds")
    gbt_leaf_nodes: int = bounded(ge=2, le=1000, description="leaves per GBT tree")
    gbt_min_samples_leaf: int = bounded(ge=1, le=100000, description="samples per GBT leaf")


class SurrogateSettings(StrictModel):
    """Surrogate candidates and how they are selected and validated."""

    regressors: list[RegressorName] = Field(min_length=1, description="candidates per output")
    classifiers: list[ClassifierName] = Field(
        min_length=1, description="scikit-learn candidates for the feasibility model"
    )
    folds: int = bounded(ge=2, le=20, description="k of the k-fold cross-validation")
    holdout_fraction: float = bounded(
        gt=0, le=0.5, description="share of the samples kept out of fitting and selection"
    )
    holdout_refit: bool = Field(
        description="after scoring, fit the selected models again with the held-out samples"
    )
    min_training_samples: int = bounded(ge=4, le=100000, description="feasible, after hold-out")
    kpls_components: int = bounded(ge=1, le=3)
    rbf_d0: float = bounded(gt=0, le=10, description="RBF basis scale, unit-cube inputs")
    phase_input: bool = Field(
        description="model dV_total by parts on the phase of the rendezvous wait (docs/optimize.md)"
    )
    selection: Literal["every_fit", "first_fit", "shortlist"] = Field(
        description="candidates compared by CV on every fit; on a pipeline's first fit and "
        "refitted unchanged on its later ones; or all on the first fit and, on the later ones, "
        "only the shortlist_size best of the first fit"
    )
    # Optional (false when absent): the configs stored with runs made before it existed
    # still read.
    burn_phase: bool = Field(
        default=False,
        description="phase_input: the phase of the rendezvous's first burn in closed form "
        "(twice its argument of latitude, ovtraj/pipeline/burn_phase.py) instead of the "
        "wait model's wait in the target's period",
    )
    # Optional (null when absent, and then off): the configs stored with runs made before
    # it existed still read.
    pass_forecast: PassForecastSettings | None = Field(
        default=None,
        description="T_total as the low-fidelity pass forecast plus a regressed residual "
        "(phase_input only)",
    )
    # Optional (empty when absent, every part on every input): the configs stored with runs
    # made before it existed still read.
    part_inputs: dict[DvPart, list[MainInput]] = Field(
        default_factory=dict,
        description="phase_input: dV parts fitted on these of the phase-input model's inputs "
        "alone (the inputs they physically depend on); the other parts on all of them",
    )
    # Optional (false when absent): the configs stored with runs made before it existed
    # still read.
    departure_phase: bool = Field(
        default=False,
        description="phase_input with pass_forecast: two more inputs, the sine and cosine of "
        "the target's mean argument of latitude from its perigee when the OV leaves it (the "
        "transfer's departure point on the target's orbit)",
    )
    # Optional (false when absent): the configs stored with runs made before it existed
    # still read.
    skip_pinned_deorbit_burns: bool = Field(
        default=False,
        description="phase_input: the deorbit part fitted without the samples whose burn the "
        "deorbit's correction pinned at the start of the preparation orbit (a costlier regime "
        "at the edge of a pass)",
    )
    # Optional (false when absent): the configs stored with runs made before it existed
    # still read.
    known_limits: bool = Field(
        default=False,
        description="phase_input: the chain's known limits on smooth quantities decide "
        "feasibility where they apply: the wait model's wait against rendezvous."
        "max_wait_time_s and, with pass_forecast, a usable deorbit pass within the horizon; "
        "the classifier learns only from samples infeasible for other reasons",
    )
    # Optional (null when absent): the configs stored with runs made before it existed
    # still read; `selection: shortlist` requires it.
    shortlist_size: int | None = bounded(
        ge=1,
        le=20,
        default=None,
        description="selection: shortlist: regressor candidates kept per output",
    )
    floor_softness_h: float = bounded(
        unit="h", gt=0, le=1000, description="T_total's predictions: softplus scale above its floor"
    )
    floor_softness_mps: float = bounded(
        unit="m/s", gt=0, le=1000, description="dV parts' predictions: softplus scale above floors"
    )
    payload_match_kg: float = bounded(
        unit="kg",
        gt=0,
        le=1.0,
        description="largest difference between the launch fit's payload and a run's M_load",
    )
    extra_trees: int = bounded(ge=1, le=10000, description="trees of the ET candidate")
    kriging_starts: int = bounded(
        ge=1, le=50, description="SMT n_start of KRG/KPLS: multistarts of the likelihood optimiser"
    )
    # SMT always adds a seeded random start to theta0; false drops it (theta0 and any LHS
    # starts of kriging_starts > 1 remain).
    kriging_random_start: bool = True
    # Cross-validation folds of KRG/KPLS started from the whole training part's optimum
    # alone (fitted first); the models kept are unchanged, only the CV figures can move.
    cv_warm_start: bool = False
    gpc_length_scale: float = bounded(
        gt=0, le=10, description="initial RBF length scale of the GP classifier, unit cube"
    )
    gpc_length_scale_bounds: Bound  # of the GP classifier's length scale, unit-cube inputs
    gpc_amplitude_bounds: Bound  # variance of the GP classifier's latent function
    seed: int = bounded(ge=0, le=2**32 - 1)
    # Optional (null when absent: every candidate on every sample, CV on all of them): the
    # configs stored with runs made before it existed still read.
    large_samples: LargeSampleSettings | None = Field(
        default=None,
        description="subsampled fits and cross-validation, and linear-cost candidates, for "
        "large training sets",
    )

    @model_validator(mode="after")
    def _shortlist_sized(self) -> SurrogateSettings:
        if self.selection == "shortlist" and self.shortlist_size is None:
            raise ValueError("selection: shortlist needs shortlist_size (candidates per output)")
        if self.departure_phase and self.pass_forecast is None:
            raise ValueError("departure_phase needs pass_forecast (the separation time)")
        phase = BURN_PHASE_INPUTS if self.burn_phase else WAIT_PHASE_INPUTS
        allowed = phase + (DEPARTURE_PHASE_INPUTS if self.departure_phase else ())
        other = set(WAIT_PHASE_INPUTS + BURN_PHASE_INPUTS + DEPARTURE_PHASE_INPUTS) - set(allowed)
        for part, names in self.part_inputs.items():
            if not names or set(names) & other:
                raise ValueError(
                    f"part_inputs.{part}: {names} must be one or more of the design's names "
                    f"and {allowed} (burn_phase {str(self.burn_phase).lower()}, "
                    f"departure_phase {str(self.departure_phase).lower()})"
                )
        return self


class ObjectivePoint(StrictModel):
    t_total_h: float = bounded(unit="h", gt=0, le=100000)
    dv_total_mps: float = bounded(unit="m/s", ge=0, le=100000)
    m_load_kg: float = bounded(unit="kg", ge=0, le=1.0e6)


class OptimizeSettings(StrictModel):
    """NSGA-II on the surrogates (pymoo) and the hypervolume's normalisation."""

    population: int = bounded(ge=4, le=100000)
    generations: int = bounded(ge=1, le=100000)
    time_limit_s: float = bounded(
        unit="s", gt=0, le=86400, description="wall time of NSGA-II on the surrogates"
    )
    seed: int = bounded(ge=0, le=2**32 - 1)
    feasibility_threshold: float = bounded(
        gt=0, lt=1, description="probability of feasibility the optimiser requires"
    )
    seed_with_real_front: bool = Field(
        description="first generation = the real non-dominated designs, topped up at random"
    )
    # Optional (null when absent, and then off): the configs stored before it existed
    # still read.
    warm_start_generations: int | None = bounded(
        ge=1,
        le=100000,
        default=None,
        description="NSGA-II of the pipeline's rounds after the first: this many generations, "
        "the first one also holding the previous round's surrogate front (null: every round "
        "like the first)",
    )
    ideal: ObjectivePoint  # maps to 0 in the normalised objectives
    reference: ObjectivePoint  # maps to 1: the hypervolume's reference point


class VerifySettings(StrictModel):
    """Verification of front points with the real chain and infill."""

    points_per_iteration: int = bounded(ge=1, le=1000)
    selection: Literal["hypervolume", "spread"] = Field(
        description="infill: greedy predicted hypervolume gain, or spread along the front"
    )
    max_iterations: int = bounded(ge=1, le=100)
    budget: int = bounded(ge=1, le=100000, description="real evaluations for infill, in all")
    tolerance: float = bounded(
        gt=0, le=1, description="surrogate error on the front, fraction of ideal-to-reference"
    )
    min_distance: float = bounded(
        ge=0, le=1, description="unit-cube distance under which a point counts as evaluated"
    )
    # Optional (null when absent, and then off): the configs stored before it existed
    # still read.
    hypervolume_tolerance: float | None = bounded(
        gt=0,
        le=1,
        default=None,
        description="stop when a round adds less than this fraction to the verified front's "
        "hypervolume",
    )
    # Optional (null when absent, and then the per-point tolerances decide): the configs
    # stored before it existed still read.
    promise_tolerance: float | None = bounded(
        gt=0,
        le=1,
        default=None,
        description="converged when the surrogates, fitted on every evaluation, promise less "
        "than this fraction of hypervolume beyond the verified front (their front's points "
        "not yet evaluated); the loop runs until then or until the budget is spent",
    )


class FrontTolerance(StrictModel):
    """How close a plan's totals must be to the front point it was picked from."""

    dv_total_mps: float = bounded(unit="m/s", gt=0, le=1000, description="|dV_total| difference")
    t_total_s: float = bounded(unit="s", gt=0, le=86400, description="|T_total| difference")
    m_load_kg: float = bounded(unit="kg", gt=0, le=1000, description="|M_load| difference")


class PlanSettings(StrictModel):
    """The mission plan and its independent replay (SPEC step 6; ``ovtraj.mission.fly``)."""

    orbit_rtol: float = bounded(gt=0, lt=1e-3, description="replay DOP853, orbital arcs")
    orbit_atol: float = bounded(
        gt=0, le=1000, description="replay DOP853, orbital arcs (m and m/s)"
    )
    entry_rtol: float = bounded(gt=0, lt=1e-3, description="replay DOP853, atmospheric entry")
    entry_atol: float = bounded(gt=0, le=1000, description="replay DOP853, entry (m, rad, m/s)")
    path_sample_step_s: float = bounded(
        unit="s", ge=0.01, le=60, description="sampling of the replayed entry for the path maxima"
    )
    prediction_tolerance_km: float = bounded(
        unit="km", gt=0, le=1000, description="replayed terminal point vs the plan's predicted one"
    )
    entry_fpa_tolerance_deg: float = bounded(
        unit="deg", ge=0, le=10, description="slack of the replayed entry angle on its limits"
    )
    # Optional: the configs stored by older versions have no promise to check.
    front_tolerance: FrontTolerance | None = Field(
        default=None,
        description="how far a plan's totals may lie from its front point's; null: unchecked",
    )


# Where the chain starts the OV (docs/rendezvous.md "Plane management"):
# launch_target: the osculating circular orbit at R_E + H_P0 the launch stage aims at (its
# insertion constraints); mean_circular: a circular orbit of J2 mean elements at H_P0 (the
# chain of configs without an insertion section).
InsertionOrbit = Literal["launch_target", "mean_circular"]
# The plane the launch aims at: rendezvous: the target's plane at the rendezvous transfer
# (the differential nodal regression over the phasing wait compensated through the
# insertion time); launch: the target's plane at insertion (the patent's choice).
PlaneStrategy = Literal["rendezvous", "launch"]


class PlaneAimSettings(StrictModel):
    """The fixed point between the aimed node and the phasing wait it gives."""

    max_iterations: int = bounded(ge=1, le=100, description="fixed-point iterations")
    tolerance_deg: float = bounded(
        unit="deg", gt=0, le=0.1, description="change of the aimed node that ends the iteration"
    )


class LaunchMatchSettings(StrictModel):
    """The plan's launch, solved to fly to the chain's insertion (ovtraj.launch.insertion)."""

    position_tolerance_m: float = bounded(
        unit="m", gt=0, le=1000, description="insertion position against the chain's"
    )
    velocity_tolerance_mps: float = bounded(
        unit="m/s", gt=0, le=10, description="insertion velocity against the chain's"
    )
    flight_time_tolerance_s: float = bounded(
        unit="s", gt=0, le=60, description="drop-to-insertion time against the chain's"
    )
    payload_ftol_kg: float = bounded(
        unit="kg", gt=0, le=10, description="SLSQP's stopping change of the payload"
    )
    max_iterations: int = bounded(ge=1, le=1000, description="SLSQP iterations")
    polish_iterations: int = bounded(
        ge=0, le=100, description="Gauss-Newton steps on the misses after SLSQP, payload held"
    )
    time_limit_s: float = bounded(unit="s", gt=0, le=86400, description="wall time (safety net)")


class InsertionSettings(StrictModel):
    """Where the chain starts the OV, and the launch that flies there."""

    orbit: InsertionOrbit
    plane: PlaneStrategy
    aim: PlaneAimSettings
    launch_match: LaunchMatchSettings


class MissionSettings(StrictModel):
    stay_h: float = bounded(
        unit="h", ge=0, le=8760, description="docked with the target after arrival"
    )
    design_bounds: MissionBoundsConfig
    # Optional: the configs stored by older versions still read, and their chain is the one
    # they were evaluated with (mean circular, the target's plane at insertion).
    insertion: InsertionSettings | None = Field(
        default=None,
        description="where the chain starts the OV and how the plan's launch flies there; "
        "null: a mean circular orbit in the target's plane at insertion",
    )
    doe: DoeSettings
    store: StoreSettings
    surrogate: SurrogateSettings
    optimize: OptimizeSettings
    verify: VerifySettings
    plan: PlanSettings
