"""Physics-informed surrogates of the mission objectives (issue 7; docs/optimize.md).

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
  argument-of-latitude rate, Brouwer 1959 via :func:`ovtraj.astro.j2_elements.secular_rates`):
  T_total, M_load, the three parts of dV_total (rendezvous, transfer, deorbit) and the
  feasibility classifier;
- dV_total is the sum of its three parts' predictions.

Both sets are ordinary :class:`~ovtraj.surrogate.SurrogateSet` (CV selection, held-out
checks, stored with their data hash); :class:`MissionSurrogates` composes them behind the
same interface (``predict``, ``feasibility``, ``cube``, names, tables).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ovtraj.astro.j2_elements import secular_rates, state_to_mean
from ovtraj.config import Scenario
from ovtraj.files import Digest, StoreError, read_json
from ovtraj.mission import DESIGN_NAMES
from ovtraj.products import Product
from ovtraj.storage import location
from ovtraj.surrogate import SurrogateError, SurrogateSet, UnitCube, fit_surrogates
from ovtraj.targets import target_state

KIND = "mission-phase-surrogates"
WAIT = "rendezvous_wait_s"
DV_PARTS = ("dv_rendezvous_mps", "dv_transfer_mps", "dv_deorbit_mps")
PHASE_INPUTS = ("sin_wait_phase", "cos_wait_phase")
MARKER = "meta.json"
PARTS = ("wait", "main")


def target_draconic_period(scenario: Scenario) -> float:
    """Period [s] of the target's argument of latitude under J2 (mean elements)."""
    earth = scenario.earth
    state = target_state(scenario.target.orbit, scenario)
    mean = state_to_mean(state[:3], state[3:], mu=earth.mu, radius=earth.radius, j2=earth.j2)
    e = math.hypot(float(mean.ex), float(mean.ey))
    _, argp_dot, m_dot = secular_rates(
        float(mean.a), e, float(mean.i), mu=earth.mu, radius=earth.radius, j2=earth.j2
    )
    return 2.0 * math.pi / (float(argp_dot) + float(m_dot))


class MissionSurrogates:
    """The wait model and the phase-input model, composed into the mission objectives."""

    output_names = ("t_total_s", "dv_total_mps", "m_load_kg")

    def __init__(
        self,
        wait: SurrogateSet,
        main: SurrogateSet,
        period_s: float,
        lower: np.ndarray,
        upper: np.ndarray,
    ) -> None:
        self.wait, self.main, self.period_s = wait, main, float(period_s)
        self.input_names = tuple(DESIGN_NAMES)
        self.cube = UnitCube(np.asarray(lower, float), np.asarray(upper, float))

    @property
    def parts(self) -> tuple[SurrogateSet, SurrogateSet]:
        return self.wait, self.main

    @property
    def selected(self) -> dict[str, str]:
        return {**self.wait.selected, **self.main.selected}

    @property
    def validation(self) -> pd.DataFrame:
        return pd.concat([self.wait.validation, self.main.validation], ignore_index=True)

    @property
    def predictions(self) -> pd.DataFrame:
        return pd.concat([self.wait.predictions, self.main.predictions], ignore_index=True)

    @property
    def data_hash(self) -> str:
        return f"{self.wait.data_hash}-{self.main.data_hash}"

    def features(self, designs: np.ndarray) -> np.ndarray:
        """Designs (m, 3) -> the main model's inputs (m, 5)."""
        designs = np.atleast_2d(np.asarray(designs, dtype=float))
        wait = self.wait.predict(designs[:, :1])[WAIT]
        phase = 2.0 * np.pi * np.mod(wait, self.period_s) / self.period_s
        return np.column_stack([designs, np.sin(phase), np.cos(phase)])

    def predict(self, designs: np.ndarray) -> dict[str, np.ndarray]:
        parts = self.main.predict(self.features(designs))
        return {
            "t_total_s": parts["t_total_s"],
            "dv_total_mps": sum(parts[name] for name in DV_PARTS),
            "m_load_kg": parts["m_load_kg"],
        }

    def feasibility(self, designs: np.ndarray) -> np.ndarray:
        return self.main.feasibility(self.features(designs))

    def save(
        self,
        directory: Path,
        *,
        meta: dict[str, Any],
        views: dict[str, Digest] | None = None,
    ) -> dict[str, Digest]:
        """``wait/`` and ``main/`` (each a stored set), then ``meta.json`` last.

        ``meta.json`` is the product's marker: it lists the digest of every file of both
        parts (their own ``meta.json`` included) and of the ``views`` (plots already
        written in ``directory``). Returns the digests, ``meta.json`` included.
        """
        directory = location(directory)
        content = {
            "kind": KIND,
            "period_s": self.period_s,
            "lower": self.cube.lower.tolist(),
            "upper": self.cube.upper.tolist(),
            "selected": self.selected,
            **meta,
        }
        with Product(directory, MARKER).writing() as out:
            for name, part in (("wait", self.wait), ("main", self.main)):
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
            digests = {name: product.digest(f"{name}/{MARKER}", meta) for name in PARTS}
        except StoreError as err:
            raise SurrogateError(str(err)) from None
        if meta.get("kind") != KIND:
            raise SurrogateError(f"{product.marker_path}: not a {KIND} directory")
        return cls(
            SurrogateSet.load(product.directory / "wait", digests["wait"]),
            SurrogateSet.load(product.directory / "main", digests["main"]),
            meta["period_s"],
            np.asarray(meta["lower"]),
            np.asarray(meta["upper"]),
        )


def load_surrogates(directory: Path) -> SurrogateSet | MissionSurrogates:
    """Whichever kind of set the directory holds."""
    try:
        marker = read_json(location(directory) / MARKER)
    except StoreError as err:
        raise SurrogateError(str(err)) from None
    if isinstance(marker, dict) and marker.get("kind") == KIND:
        return MissionSurrogates.load(directory)
    return SurrogateSet.load(directory)


def fit_mission_surrogates(
    data: Any, scenario: Scenario, lower: np.ndarray, upper: np.ndarray
) -> MissionSurrogates:
    """Fit the wait model and the phase-input model on a run's training data."""
    settings = scenario.mission.surrogate
    if not data.feasible.any():
        raise SurrogateError(f"all {len(data)} samples are infeasible: nothing to fit")
    wait = data.components[WAIT]
    known = np.isfinite(wait)
    # The wait depends on H_P0 alone: one sample per distinct H_P0 (infill points at a
    # bound share it, and repeated inputs make Kriging's correlation matrix singular).
    _, first = np.unique(data.designs[:, 0], return_index=True)
    known &= np.isin(np.arange(len(wait)), first)
    if known.sum() < settings.min_training_samples:
        raise SurrogateError(
            f"the phase input needs the rendezvous wait of at least "
            f"{settings.min_training_samples} samples; {int(known.sum())} have one"
        )
    wait_set = fit_surrogates(
        data.designs[known][:, :1],
        {WAIT: wait[known]},
        np.ones(int(known.sum()), dtype=bool),
        lower[:1],
        upper[:1],
        settings,
        input_names=DESIGN_NAMES[:1],
        sample_ids=data.sample_ids[known],
    )
    period = target_draconic_period(scenario)
    composed = MissionSurrogates(wait_set, wait_set, period, lower, upper)
    outputs = {
        "t_total_s": data.outputs["t_total_s"],
        "m_load_kg": data.outputs["m_load_kg"],
        **{name: np.where(data.feasible, data.components[name], np.nan) for name in DV_PARTS},
    }
    main = fit_surrogates(
        composed.features(data.designs),
        outputs,
        data.feasible,
        np.concatenate([lower, [-1.0, -1.0]]),
        np.concatenate([upper, [1.0, 1.0]]),
        settings,
        input_names=(*DESIGN_NAMES, *PHASE_INPUTS),
        sample_ids=data.sample_ids,
    )
    return MissionSurrogates(wait_set, main, period, lower, upper)
