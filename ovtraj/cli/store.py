"""The run store's commands: list the runs, show, verify and replay one, prune what the
store can lose (runs, show, prune, verify, replay)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from ovtraj.cli.common import (
    JsonOpt,
    StoreOpt,
    app,
    print_json,
    print_rows,
    run_store,
    store_location,
    table_console,
)
from ovtraj.config import ConfigError
from ovtraj.config.io_limits import echoed, shown_text
from ovtraj.config.orchestration import load_orchestration
from ovtraj.formatting import byte_size, number, printable, quantity, utc
from ovtraj.store.files import StoreError, read_json, tree_bytes
from ovtraj.store.records import plain
from ovtraj.version import code_version


def _families(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The run rows of the catalog by family, families newest first, each root followed by
    its runs in lineage order, with their pipeline results."""
    pipelines: dict[str, list[str]] = {}
    for row in rows:
        if row["kind"] == "pipeline":
            pipelines.setdefault(row["source"].split("/", 1)[0], []).append(row["id"])
    families: dict[str, list[dict[str, Any]]] = {}
    for row in rows:
        if row["kind"] != "run":
            continue
        entry = {
            "run_id": row["id"],
            "family": row["family"] or row["id"],
            "depth": int(row["depth"] or 0),
            "parent": row["parent"],
            "origin": row["origin"],
            "created_utc": row["created_utc"],
            "scenario": row["scenario"],
            "status": row["status"],
            "samples": row["samples"],
            "evaluated": row["evaluated"],
            "feasible": row["feasible"],
            "pipelines": pipelines.get(row["id"], []),
            "size_bytes": None,
            "error": row["error"],
        }
        families.setdefault(entry["family"], []).append(entry)

    def newest(members: list[dict[str, Any]]) -> str:
        return max(m["created_utc"] or "" for m in members)

    ordered: list[dict[str, Any]] = []
    for _, members in sorted(families.items(), key=lambda kv: newest(kv[1]), reverse=True):
        ordered += sorted(members, key=lambda m: (m["depth"], m["created_utc"] or "", m["run_id"]))
    return ordered


def _monte_carlo_runs(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The plan Monte Carlo runs of the catalog, newest first (the command's and the
    flow's alike: one store, one kind of row)."""
    found = [
        {
            "run_id": row["id"],
            "created_utc": row["created_utc"],
            "scenario": row["scenario"],
            "plan_id": row["plan_id"],
            "status": row["status"],
            "runs": row["mc_runs"],
            "landing_miss_p95_m": row["mc_landing_miss_p95_m"],
            "dv_margin_p95_mps": row["mc_dv_margin_p95_mps"],
            "size_bytes": None,
            "error": row["error"],
        }
        for row in rows
        if row["kind"] == "monte_carlo"
    ]
    return sorted(found, key=lambda m: (m["created_utc"] or "", m["run_id"]), reverse=True)


def _monte_carlo_table(runs: list[dict[str, Any]], title: str) -> Table:
    table = Table(title=title, title_justify="left", box=None, pad_edge=False)
    for column in ("run", "created (UTC)", "scenario", "plan", "status", "runs"):
        table.add_column(column, no_wrap=column == "run")
    for column in ("landing miss p95", "dV margin p95", "size"):
        table.add_column(column, justify="right")
    for m in runs:
        if m["error"] is not None:
            error = f"error: {shown_text(m['error'])}"
            table.add_row(shown_text(m["run_id"]), "-", "-", "-", error)
            continue
        table.add_row(
            shown_text(m["run_id"]),
            shown_text(utc(m["created_utc"])),
            shown_text(m["scenario"] or "-"),
            shown_text(m["plan_id"] or "-"),
            shown_text(m["status"] or "-"),
            shown_text(m["runs"] if m["runs"] is not None else "-"),
            quantity(m["landing_miss_p95_m"], "m"),
            quantity(m["dv_margin_p95_mps"], "m/s"),
            "-" if m["size_bytes"] is None else byte_size(m["size_bytes"]),
        )
    return table


def _where_table(rows: Any, title: str) -> Table:
    table = Table(title=title, title_justify="left", box=None, pad_edge=False)
    columns = (
        ("kind", "kind", ""),
        ("id", "id", ""),
        ("created (UTC)", "created_utc", "utc"),
        ("scenario", "scenario", ""),
        ("target", "target", ""),
        ("element set (UTC)", "element_set_epoch_utc", "utc"),
        ("status", "status", ""),
        ("dV_total", "dv_total_mps", "m/s"),
        ("T_total", "t_total_s", "s"),
        ("M_load", "m_load_kg", "kg"),
        ("tags", "tags", ""),
    )
    for label, _, _ in columns:
        table.add_column(label, no_wrap=label == "id")
    for row in rows.to_dict(orient="records"):
        table.add_row(
            *(
                shown_text(
                    (utc(row[key]) if unit == "utc" else quantity(row[key], unit))
                    if unit
                    else ("-" if row[key] is None or row[key] != row[key] else str(row[key]))
                )
                for _, key, unit in columns
            )
        )
    return table


@app.command()
def runs(
    store_root: StoreOpt = None,
    where: Annotated[
        str | None,
        typer.Option(
            "--where",
            help="an SQL predicate over the catalog's columns (DuckDB), e.g. \"kind = 'plan' "
            'AND dv_total_mps > 220"; lists the matching runs, pipeline results, plans '
            "and Monte Carlo runs (docs/tracking.md)",
        ),
    ] = None,
    limit: Annotated[
        int | None,
        typer.Option("--limit", help="rows shown (default catalog.rows_shown; 0: all)", min=0),
    ] = None,
    as_json: JsonOpt = False,
) -> None:
    """List the stored runs by family: each DoE run, then the runs that extend it (a
    pipeline's infill rounds, `run --append`), with their pipeline results and sizes; with
    --where, the catalog's rows (runs, pipeline results, plans) a predicate selects. The plan
    Monte Carlo runs (`ovtraj fly PLAN --monte-carlo N`, the flow) follow in a table of
    their own.

    Example: `ovtraj runs --where "kind = 'plan' AND dv_total_mps > 220"`"""
    from ovtraj.tracking.catalog import refresh
    from ovtraj.tracking.catalog_query import query
    from ovtraj.tracking.catalog_schema import catalog_settings

    root = store_location(store_root)
    try:
        found = refresh(root)
        selected = query(found.frame, where) if where else None
    except (StoreError, OSError, ValueError) as err:
        typer.echo(f"{root}: {err}", err=True)
        raise typer.Exit(code=2) from None
    shown = catalog_settings().rows_shown if limit is None else limit
    if selected is None:
        _print_runs(root, found.rows, shown, as_json)
    elif as_json:
        rows = plain(selected.to_dict(orient="records"))
        print_json({"store": str(root.resolve()), "where": where, "rows": rows})
    else:
        part = selected.iloc[-shown:] if shown else selected
        table_console().print(_where_table(part, f"catalog rows where {shown_text(where)}"))
        cut = (
            f" (the newest {len(part)} shown; --limit 0 shows all)"
            if len(part) < len(selected)
            else ""
        )
        typer.echo(f"{len(selected)} of {len(found.frame)} rows match{cut}")


def _print_runs(root: Any, rows: list[dict[str, Any]], shown: int, as_json: bool) -> None:
    """The catalog's runs by family, then its plan Monte Carlo runs, each list cut to
    ``shown`` rows (0: all; --json: all), with their sizes on disk."""
    entries = _families(rows)
    listed = entries[:shown] if shown and not as_json else entries
    monte_carlo = _monte_carlo_runs(rows)
    dispersed = monte_carlo[:shown] if shown and not as_json else monte_carlo
    _measure_sizes(root, [*listed, *dispersed])
    if as_json:
        print_json({"store": str(root.resolve()), "runs": entries, "monte_carlo": monte_carlo})
        return
    if not entries and not monte_carlo:
        typer.echo(f"no runs in {root.resolve()}")
        return
    console = table_console()
    if entries:
        console.print(_runs_table(listed, f"runs in {root.resolve()}"))
        families = sum(1 for e in entries if e["depth"] == 0)
        total = sum(e["size_bytes"] or 0 for e in listed)
        more = f" ({len(listed)} shown; --limit 0 shows all)" if len(listed) < len(entries) else ""
        typer.echo(
            f"{len(entries)} runs in {families} families{more}, {byte_size(total)} on disk "
            f"{'for those shown ' if more else ''}(a file shared by hard link counted once); "
            "`ovtraj prune` lists what can go"
        )
    _print_monte_carlo(console, dispersed, monte_carlo, root)


def _measure_sizes(root: Any, entries: list[dict[str, Any]]) -> None:
    """Each entry's ``size_bytes``, measured now, not catalogued (a run grows by its
    surrogates, fronts and pipeline results without its manifest changing); a file
    hard-linked into another listed run counts once."""
    seen: set[tuple[int, int]] = set()
    for entry in entries:
        entry["size_bytes"] = tree_bytes(root / entry["run_id"], seen)


def _runs_table(listed: list[dict[str, Any]], title: str) -> Table:
    """The runs by family, each extending run indented under the run it extends."""
    table = Table(title=title, title_justify="left", box=None, pad_edge=False)
    for column, justify in (
        ("run", "left"),
        ("created (UTC)", "left"),
        ("scenario", "left"),
        ("origin", "left"),
        ("samples", "right"),
        ("feasible", "right"),
        ("status", "left"),
        ("pipeline results", "left"),
        ("size", "right"),
    ):
        table.add_column(column, justify=justify, no_wrap=column == "run")
    for e in listed:
        indent = "  " * e["depth"] + ("└ " if e["depth"] else "")
        run = indent + shown_text(e["run_id"])
        if e["error"] is not None:
            table.add_row(run, "-", "-", "-", "-", "-", f"error: {shown_text(e['error'])}")
            continue
        table.add_row(
            run,
            shown_text(utc(e["created_utc"])),
            shown_text(e["scenario"] or "-"),
            shown_text(e["origin"] or "-"),
            shown_text(e["samples"]),
            shown_text(f"{e['feasible']}/{e['evaluated']}"),
            shown_text(e["status"] or "-"),
            ", ".join(shown_text(p) for p in e["pipelines"]) or "-",
            "-" if e["size_bytes"] is None else byte_size(e["size_bytes"]),
        )
    return table


def _print_monte_carlo(console: Console, shown: list, runs: list, root: Any) -> None:
    """The plan Monte Carlo runs' table (``shown`` of ``runs``) and its count, if any."""
    if not runs:
        return
    console.print(_monte_carlo_table(shown, f"plan Monte Carlo runs in {root.resolve()}"))
    more = f" ({len(shown)} shown; --limit 0 shows all)" if len(shown) < len(runs) else ""
    plural = "s" if len(runs) != 1 else ""
    typer.echo(f"{len(runs)} plan Monte Carlo run{plural}{more}; its pictures in RUN/plots/")


@app.command()
def show(run_id: str, store_root: StoreOpt = None, as_json: JsonOpt = False) -> None:
    """Print a run's manifest and summary as one JSON object (indented; --json: on one
    line, as every command's --json).

    Example: `ovtraj show 1fe6042587a62a93`"""

    try:
        stored = run_store(store_root).run(run_id)
        manifest, summary = stored.manifest, stored.summary()
    except StoreError as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None
    document = {"manifest": manifest, "summary": summary}
    if as_json:
        print_json(document)
        return
    typer.echo(json.dumps(document, indent=2, default=str))


PruneKinds = Annotated[
    list[str] | None,
    typer.Option(
        "--only",
        help="what to prune: children (superseded child runs), fits (surrogate fits and "
        "fronts of another code version), prefect-results (Prefect's local task results); "
        "repeat the option for several (default: all three)",
        show_default=False,
    ),
]


@app.command()
def prune(
    store_root: StoreOpt = None,
    only: PruneKinds = None,
    yes: Annotated[
        bool, typer.Option("--yes", help="delete (without it: only list what would go)")
    ] = False,
    as_json: JsonOpt = False,
) -> None:
    """List, and with --yes delete, what the store can lose without losing a result:
    child runs whose samples a later complete run holds (never a family's DoE run nor a
    pipeline's final run), surrogate fits and fronts no longer loaded by this code
    version, and Prefect's task results (a cache). See docs/mission.md.

    Example: `ovtraj prune --only children --yes`"""
    from ovtraj.pipeline.prune import KINDS, prunable, remove

    kinds = tuple(only) if only else KINDS
    unknown = sorted(set(kinds) - set(KINDS))
    if unknown:
        shown = ", ".join(echoed(repr(kind)) for kind in unknown)
        typer.echo(f"--only: {shown} is not one of {', '.join(KINDS)}", err=True)
        raise typer.Exit(code=2)
    store = run_store(store_root)
    results = load_orchestration().results.location()
    try:
        items = prunable(
            store,
            code_version(),
            kinds=kinds,
            prefect_results=None if "://" in results else Path(results),
        )
        removed = [item for item in items if yes and remove(item)]
    except (StoreError, OSError) as err:
        typer.echo(f"prune: {err}", err=True)
        raise typer.Exit(code=2) from None
    freed = sum(item.size_bytes for item in removed)
    if as_json:
        print_json(
            {
                "store": str(store.root.resolve()),
                "deleted": yes,
                "items": [i.to_json() | {"removed": i in removed} for i in items],
                "freed_bytes": freed,
            }
        )
        return
    for item in items:
        done = "deleted" if item in removed else "would delete" if not yes else "kept (in use)"
        typer.echo(f"{done}: {item.path} ({byte_size(item.size_bytes)}): {item.reason}")
    total = sum(item.size_bytes for item in items)
    if yes:
        typer.echo(f"{len(removed)} of {len(items)} items deleted, {byte_size(freed)} freed")
    else:
        typer.echo(f"{len(items)} items, {byte_size(total)}: nothing deleted (add --yes to delete)")


@app.command()
def verify(
    item_id: Annotated[
        str,
        typer.Argument(
            metavar="ID",
            help="a run, pipeline result, plan, Monte Carlo run or window id, or 'catalog'",
        ),
    ],
    store_root: StoreOpt = None,
    recompute: Annotated[
        int,
        typer.Option(
            "--recompute",
            min=0,
            help="also evaluate N of the run's samples again here (spread evenly over its "
            "sample ids) and compare every number of their stage rows and totals with the "
            "stored ones, within the tolerances of configs/reproducibility.yaml (0: checksums "
            "only; runs only)",
        ),
    ] = 0,
    as_json: JsonOpt = False,
) -> None:
    """Check every file of a stored item against its recorded size, SHA-256 and schema.

    ID is a run (its DoE or infill samples, with its surrogate fits, fronts, pipeline
    results and plans), a pipeline result or plan (checked with the run that holds
    them), a Monte Carlo run, a launch window, or 'catalog' (the catalog, its tags, and
    its rows against the store's documents). The checksums detect accidents; with
    OVTRAJ_STORE_KEY set, every manifest's and marker's seal is checked too, and one
    missing or wrong is reported as tampered. With --recompute N (a run), N stored
    samples are evaluated again on this machine: each column's largest difference is
    printed with its tolerance (docs/mission.md, "Reproducibility"). Exit 0 when every
    covered file is intact (and every recomputed column within its tolerance), 1 with the
    list of bad or tampered files (or the columns beyond), 2 when the item cannot be found,
    opened or recomputed here.

    Example: `ovtraj verify 1fe6042587a62a93 --recompute 3`
    """

    store = run_store(store_root)
    try:
        kind, label, stored, report = _verified(store, item_id)
    except StoreError as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None
    if recompute and stored is None:
        typer.echo(f"--recompute: {label} is not a run of samples", err=True)
        raise typer.Exit(code=2)
    again = _recomputed(stored, recompute) if recompute and report.clean else None
    failed = not report.clean or (again is not None and not again.ok)
    if as_json:
        document = {"kind": kind, **report.to_json()}
        if kind == "run":
            document = {"run_id": report.item_id, **document}
        print_json({**document, "recompute": None if again is None else again.to_json()})
        raise typer.Exit(code=1 if failed else 0)
    for problem in report.tampered:
        typer.echo(f"tampered: {printable(problem)}")
    for problem in report.problems:
        typer.echo(f"bad: {printable(problem)}")
    for path in report.uncovered:
        typer.echo(f"not covered by any marker (never read): {printable(path)}")
    found = [
        f"{len(found)} {what} file(s)"
        for found, what in ((report.tampered, "tampered"), (report.problems, "bad"))
        if found
    ]
    verdict = "clean" if report.clean else ", ".join(found)
    typer.echo(
        f"{label}: {report.checked_files} files, {number(report.checked_bytes / 1e6)} "
        f"MB checked: {verdict}"
    )
    if recompute and not report.clean:
        typer.echo(f"{label}: not recomputed (its files failed their checksums)")
    if again is not None:
        _print_recompute(stored, again)
    if failed:
        raise typer.Exit(code=1)


def _verified(store: Any, item_id: str) -> tuple[str, str, Any, Any]:
    """(kind, label, the run of samples or None, its VerifyReport) of what ``item_id``
    names in ``store``; StoreError naming it when the store holds nothing of that id."""
    from ovtraj.runs.ids import checked_id
    from ovtraj.tracking.catalog import verify_catalog

    if item_id == "catalog":
        return "catalog", f"the catalog of {store.root.resolve()}", None, verify_catalog(store.root)
    checked_id(item_id, "id")
    directory = store.root / item_id
    if (directory / "run.json").is_file():
        return "monte_carlo", f"Monte Carlo run {item_id}", None, _batched_run(directory).verify()
    if not directory.exists():
        from ovtraj.window.report import verify_window
        from ovtraj.window.scan import WINDOWS_DIR

        window = store.root / WINDOWS_DIR / item_id
        if window.is_dir():
            return "window", f"window {item_id}", None, verify_window(window, store)
        found = _holder(store, item_id)
        if found is not None:
            kind, run_id = found
            run = store.run(run_id)
            return kind, f"{kind} {item_id} (in run {run.id})", run, run.verify()
    run = store.run(item_id)  # StoreError naming it when the store holds no such run
    return "run", f"run {run.id}", run, run.verify()


def _holder(store: Any, item_id: str) -> tuple[str, str] | None:
    """(kind, run id) of the pipeline result or plan ``item_id`` by the catalog; None when
    it names neither (windows are looked up after)."""
    from ovtraj.tracking.catalog import refresh

    frame = refresh(store.root).frame
    rows = frame[(frame["id"] == item_id) & frame["kind"].isin(["pipeline", "plan"])]
    if not len(rows):
        return None
    row = rows.iloc[0]
    return str(row["kind"]), str(row["source"]).split("/", 1)[0]


def _batched_run(directory: Path) -> Any:
    """The Monte Carlo run in ``directory`` as its kind's class (StoreError otherwise)."""
    from ovtraj.mission.montecarlo_store import PlanMonteCarloRun
    from ovtraj.studies.deorbit_burn.store import MonteCarloRun

    info = read_json(directory / "run.json")
    kind = info.get("kind") if isinstance(info, dict) else None
    for cls in (PlanMonteCarloRun, MonteCarloRun):
        if kind == cls.KIND:
            return cls(directory)
    raise StoreError(f"{directory / 'run.json'}: not a Monte Carlo run of a known kind")


def _recomputed(stored: Any, count: int) -> Any:
    """:func:`ovtraj.runs.recompute.recompute` of ``count`` samples; one line and exit 2
    when the run cannot be recomputed here."""
    from ovtraj.runs.recompute import RecomputeError, recompute

    try:
        return recompute(stored, count)
    except (RecomputeError, StoreError, ConfigError) as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None


def _print_recompute(stored: Any, again: Any) -> None:
    """A line per compared column: its largest difference, its tolerance and the verdict."""
    shown = ", ".join(str(i) for i in again.sample_ids)
    typer.echo(
        f"recomputed here: {len(again.sample_ids)} of {len(stored.samples())} samples "
        f"(ids {shown}); the largest |stored - recomputed| of each column, and its tolerance "
        "(configs/reproducibility.yaml):"
    )
    rows = [
        (f"{c.dataset}.{c.column}", _difference(c), _tolerance(c), c.verdict) for c in again.checks
    ]
    if again.stored_code != again.code:
        typer.echo(
            f"note: the run was stored by code {again.stored_code} and is recomputed by "
            f"{again.code}: a difference may be the code's"
        )
    widths = [max(len(row[k]) for row in rows) for k in range(3)]
    for *texts, verdict in rows:
        padded = [text.ljust(width) for text, width in zip(texts, widths, strict=True)]
        typer.echo("  " + "  ".join([*padded, verdict]))
    beyond = [f"{c.dataset}.{c.column}" for c in again.beyond]
    typer.echo(
        f"run {stored.id}: recomputed {len(again.checks)} columns: "
        + (
            f"{len(beyond)} beyond their tolerance ({', '.join(beyond)})"
            if beyond
            else "all within their tolerances"
        )
    )


def _difference(check: Any) -> str:
    if check.exact:
        return f"{int(check.largest)} differ" if np.isfinite(check.largest) else "missing"
    if not np.isfinite(check.largest):
        return "missing values"
    return f"{check.largest:.3g} {check.unit}".rstrip()


def _tolerance(check: Any) -> str:
    if check.exact:
        return "exact"
    if check.tolerance is None:
        return "not bounded"
    return f"{check.tolerance:.3g} {check.unit}".rstrip()


@app.command()
def replay(run_id: str, store_root: StoreOpt = None, as_json: JsonOpt = False) -> None:
    """Re-derive the mission totals from the stored stage rows (no simulation).

    Example: `ovtraj replay 1fe6042587a62a93 --json`"""
    from ovtraj.runs import replay as replay_run

    try:
        stored = run_store(store_root).run(run_id)
        derived = replay_run(stored)
        totals = stored.totals()
    except StoreError as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None
    merged = derived.merge(totals, on="sample_id", suffixes=("", "_stored"))
    differences = {}
    for column in ("t_total_s", "dv_total_mps", "m_load_kg"):
        a, b = merged[column].to_numpy(float), merged[f"{column}_stored"].to_numpy(float)
        both = np.isfinite(a) & np.isfinite(b)
        differences[column] = float(np.max(np.abs(a[both] - b[both]))) if both.any() else 0.0
    worst = max(differences.values())
    if as_json:
        print_json(
            {
                "run_id": stored.id,
                "samples": len(derived),
                "feasible": int(derived["feasible"].sum()),
                "largest_difference": worst,
                "largest_differences": differences,
            }
        )
        return
    rows = [
        ("samples", len(derived)),
        ("feasible", int(derived["feasible"].sum())),
        ("largest difference from the stored totals", worst),
    ]
    print_rows(f"replay of {stored.id} (no simulation)", rows)
