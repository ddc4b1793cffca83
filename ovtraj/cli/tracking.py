"""The store as an experiment tracker: what changed (diff), how the plans moved (history),
the catalog (rebuilt, queried by `runs --where`), tags, and a plan's lineage
(docs/tracking.md)."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.table import Table

from ovtraj.bounded_reads import read_text_file
from ovtraj.cli.common import (
    JsonOpt,
    StoreOpt,
    app,
    print_json,
    renamed_options,
    run_store,
    store_location,
    table_console,
)
from ovtraj.config import ConfigError
from ovtraj.config.io_limits import echoed, shown_text
from ovtraj.config.orchestration import load_orchestration
from ovtraj.formatting import quantity, utc
from ovtraj.store.files import StoreError, read_json
from ovtraj.store.layout import MANIFEST, PIPELINE_MARKER
from ovtraj.store.records import plain
from ovtraj.tracking.keys import history_key


@dataclass
class _Item:
    kind: str
    label: str
    figures: list[Any]
    plan: dict[str, Any] | None = None
    plan_path: Path | None = None


def _stored_path(store: Any, catalog: Any, path: Any, field: str) -> Any:
    """``path``, built from a catalog row's ``field``, if it lies inside the store
    (:func:`ovtraj.runs.ids.within_store`): the catalog is a file like any other."""
    from ovtraj.runs.ids import within_store

    return within_store(store.root, path, f"{catalog.path}: {field}")


def _stored_plan(store: Any, catalog: Any, row: Any) -> Path:
    """The plan file of a catalog row, inside the store (:func:`_stored_path`)."""
    from ovtraj.tracking.catalog_rows import plan_file

    return Path(str(_stored_path(store, catalog, plan_file(store.root, row["source"]), "source")))


def _plan_item(store: Any, catalog: Any, path: Path, plan: dict[str, Any], label: str) -> _Item:
    from ovtraj.tracking.catalog_rows import plan_id
    from ovtraj.tracking.figures import monte_carlo_figures, plan_figures

    figures = plan_figures(plan)
    frame = catalog.frame
    runs = frame[
        (frame["kind"] == "monte_carlo")
        & (frame["plan_id"] == plan_id(plan))
        & (frame["status"] == "complete")
    ].sort_values(["created_utc", "id"])
    if len(runs):
        from ovtraj.mission.montecarlo_store import PlanMonteCarloRun
        from ovtraj.tracking.catalog_schema import checked_id

        run_id = checked_id(runs.iloc[-1]["id"], f"{catalog.path}: id")
        summary_path = _stored_path(store, catalog, store.root / run_id / "summary.json", "id")
        # Sealed, or built again from the sealed batches: an edited summary is never shown.
        summary = PlanMonteCarloRun(summary_path.parent).summary()
        figures += monte_carlo_figures(summary)
    return _Item("plan", label, figures, plan, path)


def _read_plan(path: Path) -> dict[str, Any]:
    from ovtraj.mission.plan_store import read_plan

    return read_plan(path).to_dict()


def _run_item(store: Any, run_id: str) -> _Item:
    from ovtraj.tracking.figures import run_figures

    run = store.run(run_id)
    return _Item("run", f"run {run.id}", run_figures(run.manifest, run.config, run.summary()))


def _pipeline_item(store: Any, marker: Path) -> _Item:
    from ovtraj.runs.ids import checked_id
    from ovtraj.tracking.figures import pipeline_figures

    summary = read_json(marker)
    if not isinstance(summary, dict):
        raise ValueError(f"{marker}: not a pipeline summary")
    doe = store.run(checked_id(summary.get("doe_run"), f"{marker}: doe_run"))
    label = f"pipeline {checked_id(summary.get('pipeline_id'), f'{marker}: pipeline_id')}"
    return _Item("pipeline", label, pipeline_figures(summary, doe.config))


def _resolve(store: Any, catalog: Any, ref: str) -> _Item:
    """A run, pipeline result or plan named by its id (`ovtraj runs`) or a file."""
    from ovtraj.runs.store import RunStore

    path = Path(ref)
    if path.is_dir() and (path / MANIFEST).is_file():
        return _run_item(RunStore(path.parent), path.name)
    if path.is_file():
        if path.name == MANIFEST:
            return _run_item(RunStore(path.parent.parent), path.parent.name)
        if path.name == PIPELINE_MARKER:
            return _pipeline_item(RunStore(path.parents[3]), path)
        plan = _read_plan(path)
        return _plan_item(store, catalog, path, plan, f"plan {path.name}")
    row = catalog.item(ref)
    if row["error"] is not None:
        raise ValueError(f"{ref}: {row['error']}")
    if row["kind"] == "run":
        return _run_item(store, ref)
    if row["kind"] == "pipeline":
        return _pipeline_item(
            store, _stored_path(store, catalog, store.root / row["source"], "source")
        )
    if row["kind"] == "plan":
        plan_path = _stored_plan(store, catalog, row)
        return _plan_item(store, catalog, plan_path, _read_plan(plan_path), f"plan {ref}")
    raise ValueError(f"{ref}: a {row['kind']} (diff takes runs, pipeline results and plans)")


def _fail(err: Exception) -> None:
    typer.echo(str(err), err=True)
    raise typer.Exit(code=2) from None


def _errors() -> tuple[type[Exception], ...]:
    from ovtraj.mission.plan import PlanError

    return (StoreError, ConfigError, PlanError, ValueError, OSError)


@app.command()
def diff(
    a: Annotated[str, typer.Argument(help="a run, pipeline result or plan: id or file")],
    b: Annotated[str, typer.Argument(help="the other one")],
    store_root: StoreOpt = None,
    everything: Annotated[
        bool, typer.Option("--all", help="show the unchanged figures too")
    ] = False,
    markdown: Annotated[bool, typer.Option("--md", help="a Markdown table to paste")] = False,
    as_json: JsonOpt = False,
) -> None:
    """What differs between two runs, pipeline results or plans: inputs (scenario fields,
    element set and its epoch, design, code version) and results (the plan's figures, the
    front, the Monte Carlo), each with both values, the change and its unit.

    Example: `ovtraj diff 3b8ebf38684e45f1 7c2d1e5a9f0b4c68 --md`"""
    from ovtraj.tracking.catalog import refresh
    from ovtraj.tracking.diff import changes, markdown_table, text_rows

    store = run_store(store_root)
    try:
        catalog = refresh(store.root)
        left, right = _resolve(store, catalog, a), _resolve(store, catalog, b)
    except _errors() as err:
        _fail(err)
    found = changes(left.figures, right.figures, everything=everything)
    changed = sum(c.changed for c in found)
    if as_json:
        print_json(
            {
                "a": left.label,
                "b": right.label,
                "changed": changed,
                "fields": [c.to_json() for c in found],
            }
        )
        return
    if markdown:
        typer.echo(markdown_table(found, shown_text(left.label), shown_text(right.label)))
        return
    typer.echo(f"A: {shown_text(left.label)}\nB: {shown_text(right.label)}")
    if not found:
        typer.echo("no differences")
        return
    table = Table(box=None, pad_edge=False)
    for column in ("group", "field", "A", "B", "change"):
        table.add_column(column, no_wrap=column == "field")
    for row in text_rows(found):
        table.add_row(*row)
    table_console().print(table)
    typer.echo(f"{changed} of {len(found) if everything else changed} figures differ")


_TagOpt = Annotated[
    list[str] | None,
    typer.Option("--tag", help="only the plans tagged KEY=VALUE (repeatable)"),
]


def _pairs(values: list[str] | None, what: str) -> dict[str, str]:
    found = {}
    for value in values or []:
        if "=" not in value:
            raise ValueError(f"{what} {echoed(repr(value))}: expected KEY=VALUE")
        key, _, text = value.partition("=")
        found[key] = text
    return found


# `--target-name` was `--target` (elsewhere a TLE/OMM file or URL), `--out` was `--plot`:
# still taken for one release.
@app.command(cls=renamed_options({"--target": "--target-name", "--plot": "--out"}))
def history(
    target: Annotated[
        str | None,
        typer.Option("--target-name", help="the target's name (scenario target.name)"),
    ] = None,
    scenario: Annotated[str | None, typer.Option("--scenario", help="the scenario's name")] = None,
    deployment: Annotated[
        str | None,
        typer.Option("--deployment", help="only plans of this Prefect deployment (its tag)"),
    ] = None,
    tag: _TagOpt = None,
    plot: Annotated[
        Path | None,
        typer.Option("--out", help="the trend PNG (default: STORE/catalog/history/)"),
    ] = None,
    store_root: StoreOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """The re-plans of a target in element-set order: epoch, ids, code version, launch
    epoch, dV_total, T_total, M_load, landing miss, Monte Carlo p95 and dV margin; and a
    trend plot of them with the code-version changes marked.

    Example: `ovtraj history --target-name 'ISS-like space target' --out trend.png`"""
    from ovtraj.plots.history import history_plot
    from ovtraj.tracking.catalog import refresh
    from ovtraj.tracking.catalog_schema import CATALOG_DIR
    from ovtraj.tracking.history import history as history_rows

    root = store_location(store_root)
    try:
        tags = _pairs(tag, "--tag")
        if deployment is not None:
            tags["deployment"] = deployment
        catalog = refresh(root)
        rows = history_rows(catalog, target=target, scenario=scenario, tags=tags)
    except _errors() as err:
        _fail(err)
    if not len(rows):
        typer.echo(f"no plans in {root} match", err=True)
        raise typer.Exit(code=1)
    targets = sorted(set(rows["target"].dropna()))
    name = target or (targets[0] if len(targets) == 1 else scenario or "plans")
    path = plot or Path(str(root / CATALOG_DIR / "history" / f"{history_key(name)}.png"))
    written = Path(str(history_plot(rows, path, f"re-plans of {name}"))).resolve()
    if as_json:
        print_json(
            {
                "target": name,
                "rows": plain(rows.to_dict(orient="records")),
                "plot": str(written),
            }
        )
        return
    table_console().print(_history_table(rows, f"re-plans of {shown_text(name)}"))
    typer.echo(f"plot: {written}")


def _history_table(rows: Any, title: str) -> Table:
    """A row per plan of the history: its element set, ids, code version, launch epoch and
    figures, each in its unit."""
    table = Table(title=title, title_justify="left", box=None, pad_edge=False)
    columns = (
        "element set (UTC)",
        "plan",
        "pipeline",
        "code",
        "launch (UTC)",
        "dV_total",
        "T_total",
        "M_load",
        "landing miss",
        "MC p95 miss",
        "MC dV margin",
    )
    for column in columns:
        table.add_column(column, no_wrap=True)
    for r in rows.itertuples(index=False):
        table.add_row(
            shown_text(utc(r.element_set_epoch_utc)),
            shown_text(quantity(r.plan_id)),
            shown_text(quantity(r.pipeline_id)),
            shown_text(quantity(r.code_version)),
            shown_text(utc(r.launch_epoch_utc)),
            quantity(r.dv_total_mps, "m/s"),
            quantity(r.t_total_s, "s"),
            quantity(r.m_load_kg, "kg"),
            quantity(r.landing_miss_m, "m"),
            quantity(r.mc_landing_miss_p95_m, "m"),
            quantity(r.mc_dv_margin_p95_mps, "m/s"),
        )
    return table


@app.command()
def catalog(
    rebuild: Annotated[
        bool, typer.Option("--rebuild", help="rebuild it from the stored documents alone")
    ] = False,
    store_root: StoreOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """Bring the store's catalog (one Parquet table: a row per run, pipeline result, plan and
    plan Monte Carlo) up to date, or rebuild it; prints its path.

    Example: `ovtraj catalog --rebuild`"""
    from ovtraj.tracking.catalog import refresh

    root = store_location(store_root)
    try:
        found = refresh(root, rebuild=rebuild)
    except _errors() as err:
        _fail(err)
    counts = found.frame["kind"].value_counts().to_dict()
    path = Path(str(found.path)).resolve() if "://" not in str(found.path) else found.path
    if as_json:
        print_json(
            {
                "catalog": str(path),
                "rows": len(found.frame),
                "kinds": counts,
                "written": found.written,
            }
        )
        return
    shown = ", ".join(f"{counts[k]} {k}" for k in sorted(counts)) or "empty"
    verb = "rebuilt" if rebuild else "written" if found.written else "up to date"
    typer.echo(f"catalog {verb}: {path} ({len(found.frame)} rows: {shown})")


@app.command()
def tag(
    item_id: Annotated[str, typer.Argument(help="a run, pipeline result or plan id")],
    pairs: Annotated[list[str] | None, typer.Argument(help="KEY=VALUE ...")] = None,
    remove: Annotated[
        list[str] | None, typer.Option("--remove", help="drop this tag (repeatable)")
    ] = None,
    store_root: StoreOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """Tag a stored item (tags live beside it, in the catalog's folder: its checksummed
    files never change); with no KEY=VALUE, print its tags.

    Example: `ovtraj tag 3b8ebf38684e45f1 campaign=december --remove draft`"""
    from ovtraj.tracking.catalog import refresh, set_tags
    from ovtraj.tracking.catalog_tags import read_tags

    root = store_location(store_root)
    try:
        wanted = _pairs(pairs, "tag")
        if wanted or remove:
            tags = set_tags(root, item_id, wanted, remove or [])
        else:
            refresh(root).item(item_id)
            tags = read_tags(root, item_id)
    except _errors() as err:
        _fail(err)
    if as_json:
        print_json({"id": item_id, "tags": tags})
        return
    pairs_shown = ", ".join(f"{shown_text(k)}={shown_text(v)}" for k, v in sorted(tags.items()))
    typer.echo(f"{shown_text(item_id)}: " + (pairs_shown or "no tags"))


@app.command()
def lineage(
    plan_ref: Annotated[str, typer.Argument(help="a plan (id or file) or an export of one")],
    store_root: StoreOpt = None,
    as_json: JsonOpt = False,
) -> None:
    """The chain of a plan, element set -> launch fit -> DoE run -> child runs -> surrogates
    -> front -> plan -> exports, each with its digest and whether it still verifies (exit 1
    when a link is missing or fails).

    Example: `ovtraj lineage night7.opm`"""
    from ovtraj.tracking.catalog import refresh
    from ovtraj.tracking.lineage import lineage as plan_lineage

    store = run_store(store_root)
    try:
        found = refresh(store.root)
        path = Path(plan_ref)
        if path.is_file() and path.suffix.lower() in (".oem", ".opm", ".txt", ".kvn"):
            ref = _exported_plan(path)
            row = found.item(ref)
            path = _stored_plan(store, found, row)
        elif not path.is_file():
            row = found.item(plan_ref)
            if row["kind"] != "plan":
                raise ValueError(f"{plan_ref}: a {row['kind']}, not a plan")
            path = _stored_plan(store, found, row)
        path = path.resolve()
        links = plan_lineage(store, _read_plan(path), path)
    except _errors() as err:
        _fail(err)
    broken = [link for link in links if link.state != "ok"]
    if as_json:
        print_json(
            {
                "plan": str(path.resolve()),
                "clean": not broken,
                "links": [link.to_json() for link in links],
            }
        )
    else:
        table = Table(
            title=f"lineage of {shown_text(path.resolve())}",
            title_justify="left",
            box=None,
            pad_edge=False,
        )
        for column in ("step", "item", "sha256", "state", "detail / path"):
            table.add_column(column, no_wrap=column in ("step", "item"))
        for link in links:
            table.add_row(
                shown_text(link.step),
                shown_text(link.item),
                shown_text((link.sha256 or "-")[:16]),
                link.state,
                "; ".join(shown_text(x) for x in (link.detail, link.path or "") if x),
            )
        table_console().print(table)
        verdict = "every link verifies" if not broken else f"{len(broken)} link(s) broken"
        typer.echo(verdict)
    if broken:
        raise typer.Exit(code=1)


def _exported_plan(path: Path) -> str:
    """The plan id an exported CCSDS file names (``COMMENT ovtraj plan <id>``)."""

    largest = int(load_orchestration().reads.unrecorded_file_max_mib * 2**20)
    text = read_text_file(path, max_bytes=largest, limit="reads.unrecorded_file_max_mib")
    found = re.search(r"^COMMENT ovtraj plan ([0-9a-f]{16})\b", text, flags=re.MULTILINE)
    if found is None:
        raise ValueError(f"{path}: names no ovtraj plan (no 'COMMENT ovtraj plan <id>' line)")
    return found.group(1)
