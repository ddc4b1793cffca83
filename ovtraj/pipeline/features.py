"""Physics-informed surrogates of the mission objectives (docs/optimize.md).

dV_total is dominated by the rendezvous impulse, and that impulse oscillates with the
parking altitude H_P0: the phasing wait grows smoothly with H_P0 (~1570 s per km on the
default scenario), so every ~3.5 km of H_P0 the burns turn once more around the orbit
relative to the line of nodes of the OV's and the target's J2-drifted planes, and the
share of plane change they pay follows. A design-space surrogate would need far more
samples than a DoE holds to resolve ~29 such periods; expressed in the *phase* of the
wait it is smooth. So, instead of one model per objective on the design variables:

- ``wait``: the phasing wait as a function of H_P0 alone (smooth, monotone here);
- ``main``: on (H_P0, H_dp, t_dsp, sin phi, cos phi), with
  phi = 2 pi (wait mod P) / P and P the target's draconic period under J2 (secular
  argument-of-latitude rate, Brouwer 1959 via :func:`ovtraj.astro.j2_elements.secular_rates`),
  or, with ``surrogate.burn_phase``, phi = 2 u_burn: twice the chaser's argument of
  latitude at the first burn, from the design in closed form
  (:mod:`ovtraj.pipeline.burn_phase`; the plane change the rendezvous pays follows it
  with half a revolution's period): the three parts of dV_total (rendezvous, transfer,
  deorbit), the feasibility classifier, and T_total unless ``surrogate.pass_forecast`` is
  set;
- T_total, with ``pass_forecast``: the deorbit's pass predicted in closed form from the
  design and the wait model's wait (:mod:`ovtraj.pipeline.pass_model`), plus the samples'
  median offset: it moves in whole days, which a regressor smears;
- dV_total is the sum of its three parts' predictions.

Every prediction stays in its physical range by construction:

- M_load is not regressed: it is the launch fit's payload series at H_P0, the very function
  the chain evaluates, so it is exact and inside the fit's range;
- T_total and each dV part are regressed as they are, and the prediction is passed through
  a softplus above the quantity's floor (:func:`above`): T_total above the docked stay plus
  the separation delay, which it contains by definition; each dV part above its two-body
  lower bound (:class:`DvFloors`), so dV_total stays above the sum of the floors. Far above
  its floor (more than a few ``softness``) a prediction is the regressor's own.
  Regressing log(y - floor) instead bounds them too, but measured worse (docs/optimize.md).

Both sets are ordinary :class:`~ovtraj.surrogate.SurrogateSet` (CV selection, held-out
checks, stored with their data hash); :class:`MissionSurrogates` composes them behind the
same interface (``predict``, ``feasibility``, ``cube``, names, tables), and
:func:`ovtraj.pipeline.mission_fit.fit_mission_surrogates` fits them on a run's data.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, get_args

import numpy as np
import pandas as pd

from ovtraj.astro.angles import TWO_PI
from ovtraj.astro.elements import perigee_radius
from ovtraj.astro.j2_elements import secular_rates
from ovtraj.config import Scenario
from ovtraj.config.mission import (
    BURN_PHASE_INPUTS,
    DEPARTURE_PHASE_INPUTS,
    WAIT_PHASE_INPUTS,
    DvPart,
)
from ovtraj.launch.fourier import FourierSeries
from ovtraj.mission import DESIGN_NAMES
from ovtraj.pipeline.burn_phase import BurnPhaseModel
from ovtraj.pipeline.pass_model import PassModel, target_mean_elements
from ovtraj.rendezvous.hohmann import hohmann_impulses_mps
from ovtraj.store.backends import location
from ovtraj.store.files import Digest, StoreError, read_json
from ovtraj.store.products import Product
from ovtraj.surrogate import SurrogateError, SurrogateSet, UnitCube
from ovtraj.units import S_PER_HOUR

KIND = "mission-phase-surrogates/5"
# Stored by earlier versions and still read: /4 had no known limits, /3 no burn phase.
READABLE_KINDS = ("mission-phase-surrogates/4", "mission-phase-surrogates/3")
WAIT = "rendezvous_wait_s"
PHASING_WAIT = "rendezvous_phasing_wait_s"
DEORBIT_WAIT = "deorbit_wait_s"
DEORBIT_PASSES = "deorbit_passes"
DV_PARTS = get_args(DvPart)
PHASE_INPUTS = WAIT_PHASE_INPUTS
PAYLOAD = "payload_kg"
PASS_MODEL = "pass model"  # T_total's model when it is the pass model (no regressor)
MARKER = "meta.json"
PARTS = ("wait", "main")
LIMIT_PARTS = ("phasing",)  # stored with the known limits only


def above(floor: np.ndarray, value: np.ndarray, softness: float) -> np.ndarray:
    """``floor + softness * log(1 + exp((value - floor) / softness))``: always above ``floor``.

    Equal to ``value`` within ``softness * exp(-(value - floor) / softness)`` when ``value``
    is well above the floor; ``floor + softness * log 2`` at the floor; tends to ``floor``
    far below it. (The softplus; Dugas et al. 2001.)
    """
    z = (np.asarray(value, dtype=float) - floor) / softness
    return floor + softness * np.logaddexp(0.0, z)


def _target_mean_orbit(scenario: Scenario) -> tuple[float, float, float]:
    """The target's mean semi-major axis [m], eccentricity and inclination [rad] under J2."""
    mean = target_mean_elements(scenario)
    return float(mean.a), math.hypot(float(mean.ex), float(mean.ey)), float(mean.i)


def target_draconic_period(scenario: Scenario) -> float:
    """Period [s] of the target's argument of latitude under J2 (mean elements)."""
    earth = scenario.earth
    a, e, i = _target_mean_orbit(scenario)
    _, argp_dot, m_dot = secular_rates(a, e, i, mu=earth.mu, radius=earth.radius, j2=earth.j2)
    return TWO_PI / (float(argp_dot) + float(m_dot))


@dataclass(frozen=True)
class DvFloors:
    """Two-body lower bounds [m/s] of the chain's three dV parts, per design.

    - rendezvous: the Hohmann transfer from the circular parking orbit (H_P0) to the
      target's perigee radius;
    - transfer: the Hohmann transfer from the target's perigee radius down to the circular
      preparation orbit (H_dp);
    - deorbit: the tangential burn at H_dp whose descent ellipse just reaches the entry
      interface radius, i.e. the first Hohmann impulse from H_dp down to it (the
      ``gamma_e -> 0`` limit of :func:`ovtraj.deorbit.estimate.tangential_deorbit`; a
      steeper entry costs more).

    Hohmann's is the cheapest two-impulse transfer between coplanar circular orbits
    (Vallado, 4th ed., sec. 6.3); the chain's burns also pay the plane change, the
    phasing and J2, so they only add to it. The perigee radius keeps the target's small
    eccentricity on the safe side. On 1292 feasible designs of the default scenario the
    real parts exceed these floors by at least 18.2, 1.9 and 12.5 m/s (docs/optimize.md).
    Radii in m, ``mu`` in m^3/s^2.
    """

    mu: float
    earth_radius_m: float
    target_perigee_radius_m: float
    entry_radius_m: float

    @classmethod
    def of(cls, scenario: Scenario) -> DvFloors:
        if scenario.deorbit is None:
            raise SurrogateError("the scenario has no deorbit section: no deorbit floor")
        earth = scenario.earth
        a, e, _ = _target_mean_orbit(scenario)
        return cls(
            mu=earth.mu,
            earth_radius_m=earth.radius,
            target_perigee_radius_m=perigee_radius(a, e),
            entry_radius_m=earth.radius + scenario.deorbit.entry.altitude_km * 1e3,
        )

    def __call__(self, designs: np.ndarray) -> dict[str, np.ndarray]:
        """Designs (m, 3) in DESIGN_NAMES order, km and h -> {dV part: floor (m,)}."""
        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        parking = self.earth_radius_m + designs[:, 0] * 1e3
        preparation = self.earth_radius_m + designs[:, 1] * 1e3
        target, entry, mu = self.target_perigee_radius_m, self.entry_radius_m, self.mu
        rendezvous = hohmann_impulses_mps(parking, target, mu)
        transfer = hohmann_impulses_mps(target, preparation, mu)
        deorbit, _ = hohmann_impulses_mps(preparation, entry, mu)
        return {
            "dv_rendezvous_mps": np.abs(rendezvous[0]) + np.abs(rendezvous[1]),
            "dv_transfer_mps": np.abs(transfer[0]) + np.abs(transfer[1]),
            "dv_deorbit_mps": np.abs(deorbit),
        }

    def to_dict(self) -> dict[str, float]:
        return asdict(self)


@dataclass(frozen=True)
class KnownLimits:
    """Limits of the chain on quantities the surrogates model smoothly, applied to those
    models instead of being left to the feasibility classifier (``surrogate.known_limits``).

    The cheapest designs lie where the phasing wait reaches ``rendezvous.max_wait_time_s``
    (the rendezvous costs less as H_P0 nears the target's altitude, and the wait grows):
    a model of the phasing wait (the wait the rendezvous checks against its limit, refined
    on the propagated phase, before the J2 correction moves the burn) on H_P0, trained on
    both sides of the limit, places it within ~100 s, where a classifier that knows
    nothing of the limit smears the boundary over kilometres of H_P0. And where the ground
    track crosses no entry region within the deorbit's horizon the pass model finds no
    pass either (:meth:`PassModel.has_pass`).

    ``max_wait_s``: the longest phasing wait [s] (None: not applied);
    ``pass_within_horizon``: a design needs a usable pass by the pass model.
    """

    max_wait_s: float | None
    pass_within_horizon: bool

    @classmethod
    def of(cls, scenario: Scenario, pass_model: PassModel | None) -> KnownLimits | None:
        if not scenario.mission.surrogate.known_limits:
            return None
        return cls(scenario.rendezvous.max_wait_time_s, pass_model is not None)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> KnownLimits:
        wait = data["max_wait_s"]
        return cls(None if wait is None else float(wait), bool(data["pass_within_horizon"]))

    def explained(self, data: Any, pass_model: PassModel | None = None) -> np.ndarray:
        """The infeasible samples (n,) these limits account for: a phasing wait past the
        longest allowed (the rendezvous keeps the wait it needs when it refuses one), or a
        deorbit that found no pass (none through the entry region within its horizon, or
        none within its cost bound) where ``pass_model`` finds no usable pass either."""
        feasible = np.asarray(data.feasible, dtype=bool)
        phasing = np.asarray(data.components[PHASING_WAIT], dtype=float)
        explained = np.zeros(len(phasing), dtype=bool)
        if self.max_wait_s is not None:
            explained |= phasing > self.max_wait_s
        if self.pass_within_horizon and pass_model is not None:
            # The deorbit was reached (its row holds its count of passes) and refused.
            refused = np.isfinite(np.asarray(data.components[DEORBIT_PASSES], dtype=float))
            refused &= ~feasible
            if refused.any():
                wait = np.asarray(data.components[WAIT], dtype=float)[refused]
                passless = ~pass_model.has_pass(data.designs[refused], wait)
                explained[np.flatnonzero(refused)[passless]] = True
        return explained & ~feasible


class MissionSurrogates:
    """The wait model and the phase-input model, composed into the mission objectives.

    ``payload``: the launch fit's payload series [kg] against the parking altitude [m];
    ``floors``: the dV parts' lower bounds; ``stay_s``: the docked stay [s];
    ``softness_s``, ``softness_mps``: of :func:`above`. See the module notes.
    """

    output_names = ("t_total_s", "dv_total_mps", "m_load_kg")

    def __init__(
        self,
        wait: SurrogateSet,
        main: SurrogateSet | None,
        period_s: float,
        lower: np.ndarray,
        upper: np.ndarray,
        *,
        payload: FourierSeries,
        floors: DvFloors,
        stay_s: float,
        softness_s: float,
        softness_mps: float,
        pass_model: PassModel | None = None,
        burn_phase: BurnPhaseModel | None = None,
        departure_phase: bool = False,
        limits: KnownLimits | None = None,
        phasing: SurrogateSet | None = None,
    ) -> None:
        if departure_phase and pass_model is None:
            raise SurrogateError("the departure phase needs the pass model (its separation time)")
        if limits is not None and limits.pass_within_horizon and pass_model is None:
            raise SurrogateError("the pass limit needs the pass model")
        if limits is not None and limits.max_wait_s is not None and phasing is None:
            raise SurrogateError("the wait limit needs the phasing wait's model")
        self.limits, self.phasing = limits, phasing
        self.wait, self._main, self.period_s = wait, main, float(period_s)
        self.pass_model, self.burn_phase = pass_model, burn_phase
        self.departure_phase = departure_phase
        self.payload, self.floors = payload, floors
        self.stay_s, self.softness_s, self.softness_mps = stay_s, softness_s, softness_mps
        self.input_names = tuple(DESIGN_NAMES)
        self.cube = UnitCube(np.asarray(lower, float), np.asarray(upper, float))

    @property
    def main(self) -> SurrogateSet:
        if self._main is None:
            raise SurrogateError("the phase-input model is not fitted yet")
        return self._main

    @property
    def parts(self) -> tuple[SurrogateSet, ...]:
        return (self.wait, self.main) + (() if self.phasing is None else (self.phasing,))

    @property
    def selected(self) -> dict[str, str]:
        passes = {} if self.pass_model is None else {"t_total_s": PASS_MODEL}
        chosen = {**self.wait.selected, **self.main.selected, **passes}
        if self.phasing is not None:
            chosen[PHASING_WAIT] = self.phasing.selected[PHASING_WAIT]
        return chosen

    @property
    def validation(self) -> pd.DataFrame:
        return pd.concat([part.validation for part in self.parts], ignore_index=True)

    @property
    def predictions(self) -> pd.DataFrame:
        return pd.concat([part.predictions for part in self.parts], ignore_index=True)

    @property
    def data_hash(self) -> str:
        return "-".join(part.data_hash for part in self.parts)

    def features(self, designs: np.ndarray, wait: np.ndarray | None = None) -> np.ndarray:
        """Designs (m, 3) -> the main model's inputs (m, 5, or 7 with the departure
        phase); ``wait``: their waits [s], when already predicted."""
        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        if self.burn_phase is None or self.departure_phase:
            wait = self.waits(designs) if wait is None else wait
        if self.burn_phase is not None:
            phase = self.burn_phase.phase_rad(designs)
        else:
            phase = TWO_PI * np.mod(wait, self.period_s) / self.period_s
        columns = [designs, np.sin(phase), np.cos(phase)]
        if self.departure_phase:
            departure = self.pass_model.departure_phase_rad(designs, wait)
            columns += [np.sin(departure), np.cos(departure)]
        return np.column_stack(columns)

    @property
    def phase_inputs(self) -> tuple[str, ...]:
        """The names of the main model's phase inputs (sine, cosine of each phase)."""
        phase = BURN_PHASE_INPUTS if self.burn_phase is not None else PHASE_INPUTS
        return phase + (DEPARTURE_PHASE_INPUTS if self.departure_phase else ())

    def predict(self, designs: np.ndarray) -> dict[str, np.ndarray]:
        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        parts = self.predict_parts(designs)
        return {
            "t_total_s": parts["t_total_s"],
            "dv_total_mps": sum(parts[name] for name in DV_PARTS),
            "m_load_kg": np.asarray(self.payload(designs[:, 0] * 1e3), dtype=float),
        }

    def time_floor(self, designs: np.ndarray) -> np.ndarray:
        """The docked stay plus the separation delay [s]: part of every T_total."""
        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        return self.stay_s + S_PER_HOUR * designs[:, 2]

    def waits(self, designs: np.ndarray) -> np.ndarray:
        """The wait model's phasing waits [s] of designs (m, 3)."""
        return composed_waits(self.wait, designs)

    def predict_parts(self, designs: np.ndarray) -> dict[str, np.ndarray]:
        """T_total [s] and the three dV parts [m/s], each above its floor."""
        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        wait = self.waits(designs)
        raw = self.main.predict(self.features(designs, wait))
        floors = self.floors(designs)
        if self.pass_model is None:
            t_total = raw["t_total_s"]
        else:
            t_total = self.pass_model.t_total_s(designs, wait)
        return {
            "t_total_s": above(self.time_floor(designs), t_total, self.softness_s),
            **{name: above(floors[name], raw[name], self.softness_mps) for name in DV_PARTS},
        }

    def feasibility(self, designs: np.ndarray) -> np.ndarray:
        """Probability of a feasible mission (m,): the classifier's, 0 where a known limit
        is broken."""
        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        wait = self.waits(designs)
        probability = self.main.feasibility(self.features(designs, wait))
        if self.limits is None:
            return probability
        return np.where(np.all(self._violations(designs, wait) <= 0.0, axis=1), probability, 0.0)

    def constraints(self, designs: np.ndarray, threshold: float) -> np.ndarray:
        """NSGA-II's constraints (m, k), each met when <= 0: the classifier's probability at
        least ``threshold``, then every known limit (:class:`KnownLimits`), each scaled so
        that its violation grows with the distance past the limit where it can."""
        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        wait = self.waits(designs)
        probability = self.main.feasibility(self.features(designs, wait))
        columns = [threshold - probability]
        if self.limits is not None:
            columns.append(self._violations(designs, wait))
        return np.column_stack(columns)

    def _violations(self, designs: np.ndarray, wait: np.ndarray) -> np.ndarray:
        """Each known limit's violation (m, 2), > 0 when broken: the predicted phasing wait
        past the longest allowed, as a fraction of it; 1 without a usable deorbit pass
        (``wait``: the wait model's, for the pass model)."""
        limits = self.limits
        violations = np.zeros((len(designs), 2))
        if limits.max_wait_s is not None:
            phasing = self.phasing.predict(designs[:, :1])[PHASING_WAIT]
            violations[:, 0] = (phasing - limits.max_wait_s) / limits.max_wait_s
        if limits.pass_within_horizon:
            violations[:, 1] = np.where(self.pass_model.has_pass(designs, wait), -1.0, 1.0)
        return violations

    def save(
        self,
        directory: Path,
        *,
        meta: dict[str, Any],
        views: dict[str, Digest] | None = None,
    ) -> dict[str, Digest]:
        """``wait/``, ``main/`` and, with the known limits, ``phasing/`` (each a stored set),
        then ``meta.json`` last.

        ``meta.json`` is the product's marker: it lists the digest of every file of both
        parts (their own ``meta.json`` included) and of the ``views`` (plots already
        written in ``directory``). Returns the digests, ``meta.json`` included.
        """
        directory = location(directory)
        content = {
            "kind": KIND,
            "period_s": self.period_s,
            "payload_series": self.payload.to_dict(),
            "floors": self.floors.to_dict(),
            "stay_s": self.stay_s,
            "softness_s": self.softness_s,
            "softness_mps": self.softness_mps,
            "pass_model": None if self.pass_model is None else self.pass_model.to_dict(),
            "burn_phase": None if self.burn_phase is None else self.burn_phase.to_dict(),
            "departure_phase": self.departure_phase,
            "limits": None if self.limits is None else asdict(self.limits),
            "lower": self.cube.lower.tolist(),
            "upper": self.cube.upper.tolist(),
            "selected": self.selected,
            **meta,
        }
        with Product(directory, MARKER).writing() as out:
            named = [("wait", self.wait), ("main", self.main)]
            if self.phasing is not None:
                named.append(("phasing", self.phasing))
            for name, part in named:
                # Until this marker is stored, a part's marker is an interrupted save's.
                out.discard(f"{name}/{MARKER}")
                for relative, digest in part.save(directory / name, meta=meta).items():
                    out.add(f"{name}/{relative}", digest)
            for name, digest in (views or {}).items():
                out.add(name, digest)
            out.finish(content)
        return dict(out.files)

    @classmethod
    def load(cls, directory: Path) -> MissionSurrogates:
        """Read a set written by :meth:`save`, every file checked against ``meta.json``."""
        product = Product(directory, MARKER)
        try:
            meta = product.marker()
            stored = PARTS + (LIMIT_PARTS if meta.get("limits") is not None else ())
            digests = {name: product.digest(f"{name}/{MARKER}", meta) for name in stored}
        except StoreError as err:
            raise SurrogateError(str(err)) from None
        if meta.get("kind") not in (KIND, *READABLE_KINDS):
            raise SurrogateError(
                f"{product.marker_path}: kind {meta.get('kind')!r}, not {KIND!r} "
                "(a set of another version: fit again with --refit)"
            )
        try:
            payload = FourierSeries.from_dict(meta["payload_series"])
            floors = DvFloors(**meta["floors"])
            float(meta["stay_s"]), float(meta["softness_s"]), float(meta["softness_mps"])
            passes = meta["pass_model"]
            pass_model = None if passes is None else PassModel.from_dict(passes)
            # Absent from sets of the kind before it (always the wait's phase there).
            burn = meta.get("burn_phase")
            burn_phase = None if burn is None else BurnPhaseModel.from_dict(burn)
            # Absent from sets of the kinds before it (no known limits there).
            known = meta.get("limits")
            limits = None if known is None else KnownLimits.from_dict(known)
        except (KeyError, TypeError, ValueError) as err:
            raise SurrogateError(f"{product.marker_path}: {err}") from None
        return cls(
            SurrogateSet.load(product.directory / "wait", digests["wait"]),
            SurrogateSet.load(product.directory / "main", digests["main"]),
            meta["period_s"],
            np.asarray(meta["lower"]),
            np.asarray(meta["upper"]),
            payload=payload,
            floors=floors,
            stay_s=float(meta["stay_s"]),
            softness_s=float(meta["softness_s"]),
            softness_mps=float(meta["softness_mps"]),
            pass_model=pass_model,
            burn_phase=burn_phase,
            # Absent from sets stored before it (no departure phase there).
            departure_phase=bool(meta.get("departure_phase", False)),
            limits=limits,
            phasing=None
            if limits is None
            else SurrogateSet.load(product.directory / "phasing", digests["phasing"]),
        )


def load_surrogates(directory: Path) -> SurrogateSet | MissionSurrogates:
    """Whichever kind of set the directory holds."""
    try:
        marker = read_json(location(directory) / MARKER)
    except StoreError as err:
        raise SurrogateError(str(err)) from None
    if isinstance(marker, dict) and str(marker.get("kind", "")).startswith(KIND.split("/")[0]):
        return MissionSurrogates.load(directory)
    return SurrogateSet.load(directory)


def unregressed(surrogates: SurrogateSet | MissionSurrogates) -> dict[str, str]:
    """The outputs a fitted set models without a regressor (so without CV figures), each
    with how: T_total by the pass model (:data:`PASS_MODEL`)."""
    fitted = set(surrogates.validation["model"])
    return {out: model for out, model in surrogates.selected.items() if out not in fitted}


def composed_waits(wait: SurrogateSet, designs: np.ndarray) -> np.ndarray:
    """The wait model's waits [s] of designs (m, 3) (as :meth:`MissionSurrogates.waits`)."""
    return wait.predict(np.atleast_2d(np.asarray(designs, dtype=float))[:, :1])[WAIT]
