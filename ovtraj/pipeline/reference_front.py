"""The direct reference front a pipeline's verified front is measured against.

NSGA-II on the real chain with ten times the evaluations of the direct method the
pipeline was first compared with (:mod:`ovtraj.optimize.direct`): its archive's
non-dominated designs stand in for the true front of a scenario. It is stored once per
scenario in ``data/reference/direct_front/`` (``front.parquet`` of
:data:`REFERENCE_FRONT_SCHEMA`, and ``meta.json``, written last, with the digest, the
command that made it, its seed, evaluations and hypervolume, and the scenario's key) by
``tools/direct_reference.py``.

A pipeline's hypervolume is reported as a fraction of the reference's only when the
scenario matches (:func:`scenario_key`): the settings that change the chain's results
(those a run id hashes) and the normalisation the hypervolume is measured in.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa

from ovtraj.config import Scenario
from ovtraj.mission import DESIGN_NAMES
from ovtraj.optimize import MISSION_OBJECTIVES, Normalisation
from ovtraj.optimize.direct import DirectFront
from ovtraj.paths import reference_dir
from ovtraj.runs.ids import results_config
from ovtraj.store.products import Product

FRONT = "front.parquet"
MARKER = "meta.json"
OBJECTIVE_NAMES = tuple(o.name for o in MISSION_OBJECTIVES)

REFERENCE_FRONT_SCHEMA = pa.schema(
    [
        *(pa.field(name, pa.float64(), nullable=False) for name in DESIGN_NAMES),
        *(pa.field(name, pa.float64(), nullable=False) for name in OBJECTIVE_NAMES),
    ]
)


def reference_front_directory() -> Path:
    return reference_dir() / "direct_front"


def scenario_key(scenario: Scenario) -> str:
    """What a reference front is valid for: the chain's settings (as a run id hashes them)
    and the normalisation of the objectives (ideal and reference points)."""
    optimize = scenario.mission.optimize
    content = {
        "results": results_config(scenario.resolved()),
        "ideal": optimize.ideal.model_dump(mode="json"),
        "reference": optimize.reference.model_dump(mode="json"),
    }
    text = json.dumps(content, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]


@dataclass(frozen=True)
class ReferenceFront:
    """A stored reference front: its points and its marker."""

    front: pd.DataFrame
    meta: dict[str, Any]

    @property
    def hypervolume(self) -> float:
        return float(self.meta["hypervolume"])

    def matches(self, scenario: Scenario) -> bool:
        return self.meta.get("scenario_key") == scenario_key(scenario)


def store(
    directory: Path, front: DirectFront, scenario: Scenario, document: dict[str, Any]
) -> Path:
    """Write the front and, last, the marker (never over a stored reference)."""
    product = Product(directory, MARKER)
    if product.exists():
        raise FileExistsError(f"{directory}: a reference is stored; remove it deliberately first")
    columns = {
        **{name: front.designs[:, k] for k, name in enumerate(DESIGN_NAMES)},
        **{name: front.objectives[:, k] for k, name in enumerate(OBJECTIVE_NAMES)},
    }
    table = pa.Table.from_pydict(columns, schema=REFERENCE_FRONT_SCHEMA)
    with product.writing() as writer:
        writer.write_table(FRONT, table, REFERENCE_FRONT_SCHEMA)
        writer.finish(
            document
            | {
                "scenario": scenario.name,
                "scenario_key": scenario_key(scenario),
                "front_points": len(front.objectives),
                "evaluations": front.evaluations,
                "feasible_evaluations": front.feasible_evaluations,
                "hypervolume": front.hypervolume,
            }
        )
    return directory / MARKER


def load(directory: Path | None = None) -> ReferenceFront | None:
    """The stored reference front (every file checked against the marker), or None when
    none is stored."""
    product = Product(directory or reference_front_directory(), MARKER)
    if not product.exists():
        return None
    meta = product.marker()
    return ReferenceFront(product.read_frame(FRONT, REFERENCE_FRONT_SCHEMA, meta), meta)


def reference_for(scenario: Scenario, directory: Path | None = None) -> ReferenceFront | None:
    """The stored reference front when it was made for this scenario, else None."""
    reference = load(directory)
    return reference if reference is not None and reference.matches(scenario) else None


def reference_hypervolume(reference: ReferenceFront, normalisation: Normalisation) -> float:
    """The reference front's hypervolume in ``normalisation`` (the stored figure's check)."""
    from ovtraj.optimize import hypervolume

    values = reference.front[list(normalisation.names)].to_numpy(dtype=float)
    return float(hypervolume(normalisation.normalise(np.asarray(values))))
