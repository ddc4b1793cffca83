"""The catalog row each kind of stored document gives (:mod:`ovtraj.tracking.catalog`): a
run's manifest, a pipeline result's summary, a plan's marker (and the plan it lists), a
plan Monte Carlo run's ``run.json`` and summary; and a plan's id.

Ids: a run's, a pipeline result's (``ovtraj runs``), a plan's (the first 16 hex digits of the
SHA-256 of its canonical JSON: the id the plan Monte Carlo run records), a Monte Carlo run's.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ovtraj.store.backends import S3Path, location
from ovtraj.store.batched import SUMMARY, content_id
from ovtraj.store.files import Digest, json_data, read_json
from ovtraj.store.layout import PLAN_MARKER_SUFFIX
from ovtraj.store.seals import authenticated
from ovtraj.tracking.catalog_schema import checked_id, new_row
from ovtraj.tracking.figures import element_set_epoch, target_name

__all__ = [
    "monte_carlo_row",
    "pipeline_row",
    "plan_file",
    "plan_id",
    "plan_row",
    "plan_values",
    "run_row",
]


def plan_id(plan: dict[str, Any]) -> str:
    """A plan's id: 16 hex digits of the SHA-256 of its canonical JSON (the content the
    plan Monte Carlo's run records, :mod:`ovtraj.mission.montecarlo_store`)."""
    return content_id(plan)


def plan_file(store_root: Path | S3Path, source: str) -> Path | S3Path:
    """The plan JSON of a plan row's ``source`` (its marker ``<name>.files.json``)."""
    marker = location(store_root) / source
    return marker.with_name(marker.name[: -len(PLAN_MARKER_SUFFIX)] + ".json")


def _target_columns(scenario: dict[str, Any]) -> dict[str, Any]:
    """The target's name and element-set epoch of a resolved scenario (every kind's row)."""
    return {"target": target_name(scenario), "element_set_epoch_utc": element_set_epoch(scenario)}


def run_row(directory: Path | S3Path, source: str, digest: str) -> dict[str, Any]:
    """The row of the run in ``directory`` (``source``: its manifest relative to the store,
    ``digest``: the manifest's SHA-256 as read)."""
    from ovtraj.runs.store import Run

    run = Run(directory)
    manifest = run.manifest  # checked: format, seal (with a store key)
    config = run.config
    lineage = list(manifest.get("lineage") or [])
    return new_row(
        "run",
        run.id,
        source,
        digest,
        created_utc=manifest.get("created_utc"),
        scenario=manifest.get("scenario"),
        **_target_columns(config),
        code_version=manifest.get("code_version"),
        status=manifest.get("status"),
        family=lineage[0] if lineage else run.id,
        depth=len(lineage),
        parent=manifest.get("parent"),
        run_id=run.id,
        origin=manifest.get("origin"),
        samples=manifest.get("samples"),
        evaluated=manifest.get("evaluated"),
        feasible=manifest.get("feasible"),
    )


def pipeline_row(
    marker: Path | S3Path, source: str, digest: str, payload: bytes, run: dict[str, Any]
) -> dict[str, Any]:
    """The row of a pipeline result from its summary ``payload`` (read from ``marker``, its
    seal checked with a store key); ``run``: its DoE run's row (the target's columns)."""
    summary = authenticated(marker, json_data(payload))
    if not isinstance(summary, dict):
        raise ValueError("not a JSON object")
    return new_row(
        "pipeline",
        checked_id(summary.get("pipeline_id"), "pipeline id"),
        source,
        digest,
        created_utc=summary.get("created_utc"),
        scenario=summary.get("scenario"),
        target=run.get("target"),
        element_set_epoch_utc=run.get("element_set_epoch_utc"),
        code_version=summary.get("code"),
        status="converged" if summary.get("converged") else "not converged",
        doe_run=summary.get("doe_run"),
        run_id=summary.get("final_run"),
        pipeline_id=summary.get("pipeline_id"),
        front_points=summary.get("front_points"),
        hypervolume=summary.get("hypervolume"),
        converged=summary.get("converged"),
        stop_reason=summary.get("stop_reason"),
    )


def plan_row(
    marker: Path | S3Path, source: str, digest: str, payload: bytes, pipeline: dict[str, Any]
) -> dict[str, Any]:
    """The row of a plan from its marker's ``payload`` and the plan file it lists (read by
    its digest); ``pipeline``: its pipeline result's row (the creation time)."""
    files = authenticated(marker, json_data(payload))
    name = marker.name[: -len(PLAN_MARKER_SUFFIX)]
    recorded = (files.get("files") or {}).get(f"{name}.json") if isinstance(files, dict) else None
    if recorded is None:
        raise ValueError(f"{marker.name} lists no {name}.json")
    plan = read_json(marker.parent / f"{name}.json", Digest.from_json(recorded))
    return new_row("plan", plan_id(plan), source, digest, **plan_values(plan, pipeline))


def plan_values(plan: dict[str, Any], pipeline: dict[str, Any] | None = None) -> dict[str, Any]:
    """A plan's catalog columns (its pipeline's row gives the creation time)."""
    scenario = plan.get("scenario") or {}
    source = plan.get("source") or {}
    totals = plan.get("totals") or {}
    return {
        "created_utc": (pipeline or {}).get("created_utc"),
        "scenario": scenario.get("name"),
        **_target_columns(scenario),
        "code_version": plan.get("code_version"),
        "doe_run": source.get("doe_run"),
        "run_id": source.get("run_id"),
        "pipeline_id": source.get("pipeline_id"),
        "launch_epoch_utc": (plan.get("launch") or {}).get("drop_epoch_utc"),
        "t_total_s": totals.get("t_total_s"),
        "dv_total_mps": totals.get("dv_total_mps"),
        "m_load_kg": totals.get("m_load_kg"),
        "landing_miss_m": (plan.get("terminal") or {}).get("miss_distance_m"),
    }


def monte_carlo_row(directory: Path | S3Path, source: str, digest: str) -> dict[str, Any] | None:
    """A plan Monte Carlo run's row; None for another kind of batched run."""
    from ovtraj.mission.montecarlo_store import RUN_KIND, PlanMonteCarloRun

    kind = read_json(directory / "run.json")
    if not isinstance(kind, dict) or kind.get("kind") != RUN_KIND:
        return None
    run = PlanMonteCarloRun(directory)
    info = run.info  # checked: format, kind, seal (with a store key)
    config = run.config
    plan = config.get("plan") if isinstance(config, dict) else None
    if not isinstance(plan, dict):
        raise ValueError("config.json holds no plan")
    # The summary as sealed, or built again from the sealed batches: never an edited one.
    summary = run.summary() if (directory / SUMMARY).is_file() else {}
    scenario = plan.get("scenario") or {}
    total = ((summary.get("dv_mps") or {}).get("total")) or {}
    return new_row(
        "monte_carlo",
        directory.name,
        source,
        digest,
        created_utc=info.get("created_utc"),
        scenario=scenario.get("name"),
        **_target_columns(scenario),
        code_version=info.get("code_version"),
        status=summary.get("status") or info.get("status"),
        plan_id=plan_id(plan),
        pipeline_id=(plan.get("source") or {}).get("pipeline_id"),
        mc_runs=summary.get("runs"),
        mc_landing_miss_p95_m=(summary.get("landing_miss_m") or {}).get("p95"),
        mc_dv_margin_p95_mps=total.get("p95_minus_planned"),
    )
