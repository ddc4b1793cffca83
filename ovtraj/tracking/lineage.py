"""Where a plan comes from: element set -> launch fit -> DoE run -> child runs -> surrogates
-> front -> plan -> exports, each link with its digest and whether it still verifies.

Every link is checked the way its own reader checks it: a run by :meth:`Run.verify` (every
file against its manifest or marker, the seals with a store key), a surrogate fit, the
pipeline result (its front) and the plan by their markers' digests, the launch fit by
loading it (every file checked), an export by its recorded digest. A link that is gone (a
pruned child run, a deleted fit) says ``missing``; one whose bytes changed ``FAILED`` with
the reason.
"""

from __future__ import annotations

import logging
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from ovtraj.formatting import printable
from ovtraj.runs.ids import checked_id, within_store
from ovtraj.runs.store import Run, RunStore
from ovtraj.store.batched import content_id
from ovtraj.store.files import Digest, StoreError, file_digest, read_json
from ovtraj.store.layout import PIPELINE_DIR, PIPELINE_MARKER, PLAN_MARKER_SUFFIX, PLANS_DIR
from ovtraj.store.products import Product
from ovtraj.store.seals import read_authenticated, write_sealed
from ovtraj.tracking.catalog_rows import plan_id
from ovtraj.tracking.catalog_schema import CATALOG_DIR
from ovtraj.tracking.figures import element_set_epoch

logger = logging.getLogger(__name__)

__all__ = ["EXPORTS_DIR", "Link", "lineage", "record_export"]

EXPORTS_DIR = "exports"  # <store>/catalog/exports/<plan id>.json: the plan's exported files

OK = "ok"
FAILED = "FAILED"
MISSING = "missing"


@dataclass
class Link:
    """One link of the chain: what, its id, where, its digest, ``ok | FAILED | missing``."""

    step: str
    item: str
    path: str | None
    sha256: str | None
    state: str
    detail: str = ""

    def to_json(self) -> dict[str, Any]:
        return asdict(self)


def _run_link(store: RunStore, step: str, run_id: str, what: str) -> Link:
    directory = within_store(store.root, store.root / checked_id(run_id, what), what)
    if not directory.is_dir():
        return Link(step, run_id, str(directory), None, MISSING, "not in the store (pruned?)")
    try:
        run = store.run(run_id)
        digest = file_digest(run.directory / "manifest.json").sha256
        report = run.verify()
    except (StoreError, OSError) as err:
        return Link(step, run_id, str(directory), None, FAILED, str(err))
    problems = [str(p) for p in [*report.tampered, *report.problems]]
    detail = f"{report.checked_files} files checked" if report.clean else "; ".join(problems[:3])
    return Link(step, run_id, str(directory), digest, OK if report.clean else FAILED, detail)


def _product_link(step: str, item: str, directory: Any, marker: str) -> Link:
    product = Product(directory, marker)
    if not product.exists():
        return Link(step, item, str(directory), None, MISSING, f"no {marker}")
    try:
        content = product.marker()
        for name in sorted(content["files"]):
            product.read_bytes(name, content)
        digest = file_digest(product.marker_path).sha256
    except (StoreError, OSError, ValueError) as err:
        return Link(step, item, str(directory), None, FAILED, str(err))
    return Link(
        step, item, str(product.marker_path), digest, OK, f"{len(content['files'])} files checked"
    )


def _launch_fit_link(config: dict[str, Any]) -> Link:
    from ovtraj.config.scenario import scenario_from_dict
    from ovtraj.errors import ConfigError
    from ovtraj.launch.launch_fit import find_launch_fit, launch_fit_key

    try:
        scenario = scenario_from_dict(config, "the DoE run's config.json")
        key = launch_fit_key(scenario)
    except (ConfigError, ValueError) as err:
        return Link("launch fit", "-", None, None, FAILED, str(err))
    try:
        fit = find_launch_fit(scenario)
    except (StoreError, OSError, ValueError) as err:
        return Link("launch fit", key, None, None, FAILED, str(err))
    if fit is None:
        return Link("launch fit", key, None, None, MISSING, "no stored fit of this key")
    directory = getattr(fit, "directory", None)
    return Link(
        "launch fit",
        key,
        None if directory is None else str(directory),
        key,
        OK,
        "loaded, every file checked",
    )


def record_export(plan_path: Path, plan: dict[str, Any], export: Path, fmt: str) -> Path | None:
    """Note ``export`` of a plan stored in a run store (``<store>/<run>/pipeline/<id>/plans/``)
    beside the store's catalog, for :func:`lineage`; None for a plan outside a store."""
    plan_path = plan_path.resolve()
    if plan_path.parent.name != PLANS_DIR or plan_path.parents[2].name != PIPELINE_DIR:
        return None
    root = plan_path.parents[4]
    record = root / CATALOG_DIR / EXPORTS_DIR / f"{plan_id(plan)}.json"
    exports = _exports(record)
    exports[str(export.resolve())] = {"format": fmt, **file_digest(export).to_json()}
    document = {"plan": plan_id(plan), "exports": dict(sorted(exports.items()))}
    write_sealed(record, document, replace=True)
    return record


def _exports(record: Path) -> dict[str, dict[str, Any]]:
    if not record.is_file():
        return {}
    try:  # sealed with a store key: a forged record names no file to hash
        document = read_authenticated(record)
    except StoreError as err:
        logger.warning("%s; its exports are not listed", err)
        return {}
    found = document.get("exports") if isinstance(document, dict) else None
    return found if isinstance(found, dict) else {}


def _export_links(store: RunStore, the_plan: str) -> list[Link]:
    links = []
    record = store.root / CATALOG_DIR / EXPORTS_DIR / f"{the_plan}.json"
    for path, recorded in _exports(record).items() if isinstance(record, Path) else []:
        target = Path(path)
        if not target.is_file():
            links.append(
                Link("export", recorded.get("format", "-"), path, None, MISSING, "file gone")
            )
            continue
        try:
            expected = Digest.from_json(recorded)
            found = file_digest(target)
        except (ValueError, StoreError, OSError) as err:
            links.append(Link("export", "-", path, None, FAILED, str(err)))
            continue
        same = found == expected
        links.append(
            Link(
                "export",
                recorded.get("format", "-"),
                path,
                found.sha256,
                OK if same else FAILED,
                "as exported" if same else "changed since it was exported",
            )
        )
    return links


def _stored_ids(
    store: RunStore, ids: dict[str, Any], fields: tuple[str, ...], what: str
) -> dict[str, str | None]:
    """The ids ``fields`` of ``ids`` (a document read from a file), each checked as one
    typed on the command line (:func:`checked_id`) before any path is built from it, and
    the folder it names inside the store; None for one the document does not give.
    :class:`StoreError` naming ``what`` (the file) and the field otherwise: followed as
    written, a plan whose ``source.pipeline_id`` is ``../../../../outside/x`` would have
    files outside the store read and verified as its chain."""
    found: dict[str, str | None] = {}
    for field in fields:
        value = ids.get(field)
        if value is not None:
            name = f"{what}.{field}"
            within_store(store.root, store.root / checked_id(value, name), name)
        found[field] = value
    return found


def lineage(store: RunStore, plan: dict[str, Any], plan_path: Path | None) -> list[Link]:
    """The chain of a plan (its parsed JSON and, when stored, its file), each link checked;
    an id the plan or a stored document gives that is not an id of the store is a
    :class:`StoreError` naming the file and the field, raised before anything is read."""
    source = plan.get("source") or {}
    origin = f"{printable(str(plan_path))}: source" if plan_path is not None else "plan source"
    ids = _stored_ids(store, source, ("doe_run", "pipeline_id"), origin)
    doe_id, pipeline_id = ids["doe_run"], ids["pipeline_id"]
    links = [_element_set_link(plan), *_doe_links(store, doe_id, origin)]
    pipeline_dir = store.root / str(doe_id) / PIPELINE_DIR / str(pipeline_id)
    summary_file = pipeline_dir / PIPELINE_MARKER
    summary: Any = {}
    if doe_id and pipeline_id:
        within_store(store.root, pipeline_dir, f"{origin}.pipeline_id")
    if doe_id and pipeline_id and summary_file.is_file():
        try:
            summary = read_json(summary_file)
        except StoreError:
            summary = {}
    links += _round_links(store, summary, summary_file)
    if pipeline_id:
        links.append(
            _product_link(
                "front (pipeline result)", str(pipeline_id), pipeline_dir, PIPELINE_MARKER
            )
        )
    the_plan = plan_id(plan)
    if plan_path is not None:
        links.append(_plan_link(the_plan, plan_path))
    return links + _export_links(store, the_plan)


def _element_set_link(plan: dict[str, Any]) -> Link:
    """The element set the plan was made from (inline in the plan: its digest)."""
    scenario = plan.get("scenario") or {}
    target = scenario.get("target") or {}
    element_set = {k: target[k] for k in ("tle", "omm", "orbit") if k in target}
    kind = "tle" if "tle" in target else "omm" if "omm" in target else "hand-typed orbit"
    return Link(
        "element set",
        f"{kind}, epoch {element_set_epoch(scenario)}",
        None,
        content_id(element_set),
        OK,
        "inline in the plan and in the DoE run's config.json",
    )


def _doe_links(store: RunStore, doe_id: str | None, origin: str) -> list[Link]:
    """The launch fit (found from the DoE run's config) and the DoE run; none without a DoE
    run id. ``origin``: where the id was read (the plan file's source)."""
    if not doe_id:
        return []
    links: list[Link] = []
    config: dict[str, Any] | None = None
    if (store.root / doe_id / "manifest.json").is_file():
        try:
            config = Run(store.root / doe_id).config
        except StoreError as err:
            links.append(Link("launch fit", "-", None, None, FAILED, str(err)))
    if config is not None:
        links.append(_launch_fit_link(config))
    else:
        links.append(Link("launch fit", "-", None, None, MISSING, "the DoE run is not stored"))
    links.append(_run_link(store, "DoE run", doe_id, f"{origin}.doe_run"))
    return links


def _round_links(store: RunStore, summary: Any, summary_file: Any) -> list[Link]:
    """The surrogate fit and the child run of each round of a pipeline result (its
    ``summary``, read from ``summary_file``), their ids checked before any is followed."""
    links: list[Link] = []
    iterations = summary.get("iterations", []) if isinstance(summary, dict) else []
    for k, step in enumerate(iterations if isinstance(iterations, list) else []):
        what = f"{printable(str(summary_file))}: iterations[{k}]"
        if not isinstance(step, dict):
            raise StoreError(f"{what}: not a JSON object")
        _stored_ids(store, step, ("run_id", "infill_run"), what)
        child = step.get("infill_run")
        if step.get("run_id") and step.get("fit_id"):
            fit_id = checked_id(step["fit_id"], f"{what}.fit_id")
            fit_dir = within_store(
                store.root,
                store.root / step["run_id"] / "surrogates" / fit_id,
                f"{what}.fit_id",
            )
            step_name = f"surrogates (round {step.get('iteration')})"
            links.append(_product_link(step_name, step["fit_id"], fit_dir, "meta.json"))
        if child:
            step_name = f"child run (round {step.get('iteration')})"
            links.append(_run_link(store, step_name, child, f"{what}.infill_run"))
    return links


def _plan_link(the_plan: str, plan_path: Path) -> Link:
    """The plan file: checked against its marker when stored, else its digest alone."""
    name = plan_path.name.rsplit(".", 1)[0]
    marker = f"{name}{PLAN_MARKER_SUFFIX}"
    if (plan_path.parent / marker).is_file():
        return _product_link("plan", the_plan, plan_path.parent, marker)
    return Link(
        "plan",
        the_plan,
        str(plan_path),
        file_digest(plan_path).sha256,
        OK,
        "a plan file outside the store: no marker to check it against",
    )
