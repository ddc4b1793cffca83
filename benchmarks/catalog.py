"""The store's catalog on a synthetic store of 10,000 runs: refresh, read, query and the
``ovtraj runs`` commands, side by side in one process.

The store (a temporary folder) holds ``--runs`` runs in families of ``--family-size``: one
night's re-plan of one of four targets, a DoE run and its infill runs (``parent``,
``lineage``), one pipeline result in the DoE run and one plan, the nights going back a day
at a time; every ``--tag-every``-th plan is tagged. It is made from real parts:

- one run created by the run store (``RunStore.create``) from the default scenario
  (``configs/scenario.yaml``), its 2-sample DoE evaluated and stored (batches, stages,
  trajectories, totals), and one plan built by ``plan_and_record`` (the shipped launch fit);
- replicated: each run a directory of its own with the template's data files hard-linked
  (as a child run holds its parent's batches), its own ``config.json`` (the resolved
  scenario with the family's target name and element-set epoch) and its own
  ``manifest.json`` (run id, parent, lineage, times, code version, origin; sealed when
  ``OVTRAJ_STORE_KEY`` is set); the pipeline summaries as the pipeline writes them (its
  fields, its iterations; no front files: the catalog reads the summary only); each plan
  the real one with the family's scenario, ids, launch epoch and key figures, and its
  ``.files.json`` marker. The documents are built by the store's own functions
  (``json_text``, ``sealed``, ``Digest``, ``plan_json``) but written without the store's
  ``fsync`` per file: durability is not what is measured. ``RunStore.create`` alone (an
  empty run: no batches) is timed on a few runs for comparison (``create_s_per_run``).

Measured (medians; the machine is shared and noisy): ``refresh(root, rebuild=True)`` (the
catalog from the documents alone: ``ovtraj catalog --rebuild``), ``refresh(root)`` with
nothing changed (the check every command does first) and after one new run, reading the
catalog file alone (its digest checked), ``query(frame, where)`` for the example question
("every plan for target X since Monday with dV_total above 220 m/s") and a query of runs,
and ``ovtraj runs --store ROOT`` and ``ovtraj runs --store ROOT --where ...`` as a user runs
them (the ``ovtraj`` next to this Python, output to a pipe, wall time). Two commands show
what they spend before any work on the store: ``ovtraj --help`` (the command line's
start-up) and ``ovtraj runs`` on an empty store (its start-up and its own imports).

Goals: a query over 10,000 runs under 1 s; ``ovtraj runs`` under 2 s on it.

Run: ``python benchmarks/catalog.py [--runs 10000] [--family-size 4] [--tag-every 10]
[--repeats 3] [--json]``; ``--repeats`` for the rebuild and the commands (the fast
in-process figures take 5). The last line is one JSON object with the figures, the goals
and the ratios (``--json`` prints only that line).
"""

from __future__ import annotations

import argparse
import copy
import datetime
import hashlib
import json
import os
import random
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from goals import goal as benchmark_goal

from ovtraj.launch.launch_fit import find_launch_fit
from ovtraj.mission import DESIGN_NAMES, MissionContext, MissionDesign, reference
from ovtraj.mission.plan import MissionPlan, PlanError
from ovtraj.mission.plan_build import plan_and_record
from ovtraj.mission.plan_store import plan_json
from ovtraj.runs import RunStore, execute, latin_hypercube
from ovtraj.runs.ids import results_hash
from ovtraj.store.files import Digest
from ovtraj.store.layout import (
    MANIFEST,
    PIPELINE_DIR,
    PIPELINE_MARKER,
    PLAN_MARKER_SUFFIX,
    PLANS_DIR,
)
from ovtraj.store.products import digests_json
from ovtraj.store.records import json_text
from ovtraj.store.seals import sealed
from ovtraj.target_sources import load_scenario
from ovtraj.tracking import catalog
from ovtraj.tracking.catalog import refresh
from ovtraj.tracking.catalog_query import query
from ovtraj.tracking.catalog_rows import plan_id
from ovtraj.tracking.catalog_schema import CATALOG_DIR, KINDS
from ovtraj.tracking.catalog_tags import TAGS_DIR

ROOT = Path(__file__).resolve().parents[1]
OVTRAJ = Path(sys.executable).with_name("ovtraj")
QUERY_GOAL_S = benchmark_goal("catalog", "query_s")  # a query over 10,000 runs
RUNS_COMMAND_GOAL_S = benchmark_goal("catalog", "runs_command_s")  # `ovtraj runs` on them
FAST_REPEATS = 5  # the in-process figures of milliseconds
TEMPLATE_SAMPLES = 2  # the template run's DoE (evaluated once)
CREATE_SAMPLE_RUNS = 10  # runs made by RunStore.create to show its cost per run
# The family's target; the first is the default scenario's.
TARGETS = (
    "ISS-like space target",
    "Tiangong-like station",
    "Debris object 43013",
    "Demonstrator MARIO",
)
LAST_NIGHT = datetime.datetime(2026, 12, 6, tzinfo=datetime.UTC)  # a Sunday: a whole week
CODE_VERSION_NIGHTS = 60  # a new code version every this many nights
DV_LIMIT_MPS = 220.0  # the example question's limit


def _iso(moment: datetime.datetime) -> str:
    return moment.isoformat(timespec="seconds")


def _median(run, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def _put(path: Path, payload: bytes) -> Digest:
    """The store's bytes of a file, without its fsync (see the module notes)."""
    path.write_bytes(payload)
    return Digest.of(payload)


def _json_bytes(value) -> bytes:
    return (json_text(value) + "\n").encode("utf-8")  # as ovtraj.store.files.write_json


# --- the template: one real run and one real plan -----------------------------------------
def _template(scenario, store: RunStore):
    """A run of the default scenario with its DoE evaluated and stored, and a plan of one
    of its feasible designs (else of the reference designs)."""
    context = MissionContext(scenario, find_launch_fit(scenario))
    samples = latin_hypercube(scenario.mission.design_bounds, TEMPLATE_SAMPLES, 0)
    records = execute.evaluate_batch(context, samples)
    run = store.create(resolved=scenario.resolved(), samples=samples, seed=0, code="bench")
    ids = [int(i) for i in samples["sample_id"]]
    with run.claim(0):
        run.write_batch(0, records, ids, trajectory_steps=execute.trajectory_steps(scenario))
    execute.finish(run)
    designs = [
        MissionDesign(**{name: float(row[name]) for name in DESIGN_NAMES})
        for (_, row), record in zip(samples.iterrows(), records, strict=True)
        if record.feasible
    ]
    designs += reference.designs(scenario, reference.load_settings())
    source = {"doe_run": run.id, "run_id": run.id, "pipeline_id": "0" * 16}
    for design in designs:
        try:
            return run, plan_and_record(context, design, source=source)[0].to_dict()
        except PlanError:
            continue  # an infeasible design: the next
    raise SystemExit("no feasible design for the template plan")


def _runstore_create_s(scenario, store: RunStore) -> float:
    """Seconds per run of RunStore.create (a 1-sample run, a new seed each)."""
    samples = latin_hypercube(scenario.mission.design_bounds, 1, 0)
    resolved = scenario.resolved()
    start = time.perf_counter()
    for seed in range(CREATE_SAMPLE_RUNS):
        store.create(resolved=resolved, samples=samples, seed=seed, code="bench-create")
    return (time.perf_counter() - start) / CREATE_SAMPLE_RUNS


# --- the synthetic store ------------------------------------------------------------------
class Builder:
    """Families of runs made from the template (see the module notes)."""

    def __init__(self, root: Path, template, plan: dict, family_size: int, tag_every: int):
        self.root, self.family_size, self.tag_every = root, family_size, tag_every
        self.template_dir = template.directory
        self.manifest = template.manifest
        self.resolved = template.config
        self.plan = plan
        self.rng = random.Random(46)
        # The template's data files (locks excluded: a hard-linked lock would be shared).
        self.data_files = [
            path.relative_to(self.template_dir)
            for path in sorted(self.template_dir.rglob("*"))
            if path.is_file()
            and path.name not in (MANIFEST, "config.json")
            and path.relative_to(self.template_dir).parts[0] != "locks"
        ]
        self.folders = sorted({p.parent for p in self.data_files if p.parent != Path(".")})
        self.plans = 0

    def _id(self) -> str:
        return f"{self.rng.getrandbits(64):016x}"

    def run(self, config_bytes: bytes, config_digest: Digest, values: dict) -> str:
        run_id = self._id()
        directory = self.root / run_id
        directory.mkdir()
        for folder in self.folders:
            (directory / folder).mkdir(parents=True, exist_ok=True)
        for name in self.data_files:
            os.link(self.template_dir / name, directory / name)
        _put(directory / "config.json", config_bytes)
        files = dict(self.manifest["files"], **{"config.json": config_digest.to_json()})
        manifest = {**self.manifest, "run_id": run_id, **values, "files": files}
        _put(directory / MANIFEST, _json_bytes(sealed(directory / MANIFEST, manifest)))
        return run_id

    def family(self, night: int, nights: int, target: int) -> None:
        """One night's re-plan of one target: its runs, pipeline result and plan."""
        day = LAST_NIGHT - datetime.timedelta(days=nights - 1 - night)
        element_set = day - datetime.timedelta(hours=9)  # yesterday's element set
        code = f"0.1.{night // CODE_VERSION_NIGHTS}+g"
        code += hashlib.sha256(code.encode()).hexdigest()[:12]
        config = copy.deepcopy(self.resolved)
        config["target"]["name"] = TARGETS[target]
        config["epoch_utc"] = element_set.strftime("%Y-%m-%dT%H:%M:%SZ")
        config_bytes = _json_bytes(config)
        config_digest = Digest.of(config_bytes)
        lineage: list[str] = []
        start = day + datetime.timedelta(hours=1, minutes=5 * target)
        for k in range(self.family_size):
            values = {
                "parent": lineage[-1] if lineage else None,
                "lineage": list(lineage),
                "created_utc": _iso(start + datetime.timedelta(minutes=20 * k)),
                "code_version": code,
                "results_hash": results_hash(config),
                "seed": night,
                "origin": f"infill {k}" if k else "latin hypercube",
            }
            lineage.append(self.run(config_bytes, config_digest, values))
        created = _iso(start + datetime.timedelta(minutes=20 * self.family_size))
        self._pipeline(lineage, config, code, created)

    def _pipeline(self, lineage: list[str], config: dict, code: str, created: str) -> None:
        doe_run, final_run, pipeline_id = lineage[0], lineage[-1], self._id()
        directory = self.root / doe_run / PIPELINE_DIR / pipeline_id
        (directory / PLANS_DIR).mkdir(parents=True)
        front_points = self.rng.randint(3, 40)
        summary = {
            "pipeline_id": pipeline_id,
            "doe_run": doe_run,
            "final_run": final_run,
            "scenario": config["name"],
            "code": code,
            "stop_reason": "front stable",
            "converged": True,
            "real_evaluations": {"doe": TEMPLATE_SAMPLES, "infill": len(lineage) - 1},
            "front_points": front_points,
            "hypervolume": round(self.rng.uniform(0.5, 0.9), 6),
            "reference_point": [1.1, 1.1, 1.1],
            "ideal_point": [0.0, 0.0, 0.0],
            "iterations": [
                {
                    "iteration": k,
                    "run_id": run_id,
                    "samples": TEMPLATE_SAMPLES + k,
                    "feasible": 1 + k,
                    "fit_id": self._id(),
                    "selected": {"dv_total_mps": "KRG", "t_total_s": "RBF", "m_load_kg": "KRG"},
                    "surrogate_front_points": front_points,
                    "surrogate_hypervolume": round(self.rng.uniform(0.5, 0.9), 6),
                }
                for k, run_id in enumerate(lineage[:-1], start=1)
            ],
            "created_utc": created,
            "files": {},
        }
        marker = directory / PIPELINE_MARKER
        _put(marker, _json_bytes(sealed(marker, summary)))
        self._plan(directory / PLANS_DIR, summary, config, code)

    def _plan(self, directory: Path, summary: dict, config: dict, code: str) -> None:
        plan = copy.deepcopy(self.plan)
        sample_id = self.rng.randint(0, 99)
        totals = plan["totals"]
        # dV_total spread around the example query's limit: ~30 % of the plans above it
        scale = 0.96 + 0.08 * self.rng.gauss(0.0, 1.0)
        totals["dv_total_mps"] = DV_LIMIT_MPS * scale
        totals["t_total_s"] *= 1.0 + 0.05 * self.rng.gauss(0.0, 1.0)
        totals["m_load_kg"] *= 1.0 + 0.02 * self.rng.gauss(0.0, 1.0)
        plan["terminal"]["miss_distance_m"] = abs(self.rng.gauss(0.0, 200.0))
        plan["code_version"] = code
        plan["scenario"]["target"]["name"] = config["target"]["name"]
        plan["scenario"]["epoch_utc"] = config["epoch_utc"]
        day = datetime.datetime.fromisoformat(summary["created_utc"]).date()
        plan["launch"]["drop_epoch_utc"] = f"{day + datetime.timedelta(days=1)}T12:03:04Z"
        plan["source"].update(
            doe_run=summary["doe_run"],
            run_id=summary["final_run"],
            pipeline_id=summary["pipeline_id"],
            sample_id=sample_id,
        )
        name = f"plan-sample-{sample_id}"
        # Validated as a plan, written as ovtraj.mission.plan_store.write_plan writes its JSON.
        payload = plan_json(MissionPlan.model_validate(plan))
        digest = _put(directory / f"{name}.json", payload)
        marker = directory / f"{name}{PLAN_MARKER_SUFFIX}"
        document = {"plan": name, "files": digests_json({f"{name}.json": digest})}
        _put(marker, _json_bytes(sealed(marker, document)))
        self.plans += 1
        if self.tag_every and self.plans % self.tag_every == 0:
            self._tag(plan_id(json.loads(payload)))

    def _tag(self, item_id: str) -> None:
        """As ``ovtraj tag ID reviewed=yes`` writes it (ovtraj.tracking.catalog.set_tags)."""
        folder = self.root / CATALOG_DIR / TAGS_DIR
        folder.mkdir(parents=True, exist_ok=True)
        document = {"id": item_id, "tags": {"reviewed": "yes"}}
        _put(folder / f"{item_id}.json", json.dumps(document, indent=1).encode())


# --- the commands -------------------------------------------------------------------------
def _command_s(command: list[str], repeats: int) -> tuple[float, int]:
    """Median wall time of ``command`` (output to a pipe) and its output's lines."""
    times, lines = [], 0
    for _ in range(repeats):
        start = time.perf_counter()
        done = subprocess.run(command, capture_output=True, check=False)
        times.append(time.perf_counter() - start)
        if done.returncode != 0:
            raise SystemExit(f"{' '.join(command)} failed:\n{done.stderr.decode()}")
        lines = done.stdout.count(b"\n")
    return statistics.median(times), lines


def _predicates(nights: int) -> dict[str, str]:
    last = LAST_NIGHT.date()
    monday = last - datetime.timedelta(days=last.weekday())
    month = LAST_NIGHT - datetime.timedelta(days=min(30, nights - 1), hours=12)
    return {
        # the example question: every plan for target X since Monday with dV_total above 220
        "plans": f"kind = 'plan' AND target = '{TARGETS[0]}' AND created_utc >= '{monday}' "
        f"AND dv_total_mps > {DV_LIMIT_MPS:g}",
        "runs": f"kind = 'run' AND target = '{TARGETS[1]}' AND status = 'complete' "
        f"AND element_set_epoch_utc >= '{month:%Y-%m-%dT%H:%M:%S}'",
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10_000)
    parser.add_argument("--family-size", type=int, default=4, help="runs per night's re-plan")
    parser.add_argument("--tag-every", type=int, default=10, help="tag every n-th plan")
    parser.add_argument("--repeats", type=int, default=3, help="of the rebuild, the commands")
    parser.add_argument("--json", action="store_true", help="print only the JSON line")
    args = parser.parse_args()
    families = max(1, args.runs // args.family_size)
    runs = families * args.family_size
    nights = -(-families // len(TARGETS))
    scenario = load_scenario(ROOT / "configs" / "scenario.yaml")
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        template, plan = _template(scenario, RunStore(Path(tmp) / "template"))
        template_s = time.perf_counter() - start
        create_s = _runstore_create_s(scenario, RunStore(Path(tmp) / "created"))
        root = Path(tmp) / "runs"
        root.mkdir()
        builder = Builder(root, template, plan, args.family_size, args.tag_every)
        start = time.perf_counter()
        for f in range(families):
            builder.family(f // len(TARGETS), nights, f % len(TARGETS))
        build_s = time.perf_counter() - start

        rebuild_s = _median(lambda: refresh(root, rebuild=True), args.repeats)
        unchanged_s = _median(lambda: refresh(root), FAST_REPEATS)
        found = refresh(root)
        assert not found.written, "an unchanged store rewrote its catalog"
        frame = found.frame
        catalog_bytes = (root / CATALOG_DIR / catalog.CATALOG_FILE).stat().st_size
        read_s = _median(lambda: catalog._read(root), FAST_REPEATS)
        where = _predicates(nights)
        query_s = {k: _median(lambda w=w: query(frame, w), FAST_REPEATS) for k, w in where.items()}
        matched = {k: len(query(frame, w)) for k, w in where.items()}
        startup_s, _ = _command_s([str(OVTRAJ), "--help"], args.repeats)
        (Path(tmp) / "empty").mkdir()
        empty = [str(OVTRAJ), "runs", "--store", str(Path(tmp) / "empty")]
        empty_s, _ = _command_s(empty, args.repeats)
        listing = [str(OVTRAJ), "runs", "--store", str(root)]
        runs_s, runs_lines = _command_s(listing, args.repeats)
        where_s, where_lines = _command_s([*listing, "--where", where["plans"]], args.repeats)

        def one_more_run() -> None:  # a new night's DoE run, then the refresh
            builder.run(
                (template.directory / "config.json").read_bytes(),
                Digest.of((template.directory / "config.json").read_bytes()),
                {"created_utc": _iso(LAST_NIGHT + datetime.timedelta(days=1))},
            )
            refresh(root)

        new_run_s = _median(one_more_run, FAST_REPEATS)  # last: the store grows by 5 runs
    rows = len(frame)
    by_kind = {kind: int((frame["kind"] == kind).sum()) for kind in KINDS}
    errors = int(frame["error"].notna().sum())
    ratios = {
        "query_plans": round(query_s["plans"] / QUERY_GOAL_S, 4),
        "query_runs": round(query_s["runs"] / QUERY_GOAL_S, 4),
        "runs_command": round(runs_s / RUNS_COMMAND_GOAL_S, 3),
        "runs_where_command": round(where_s / RUNS_COMMAND_GOAL_S, 3),
    }
    figures = {
        "runs": runs,
        "families": families,
        "nights": nights,
        "rows": rows,
        "rows_by_kind": by_kind,
        "row_errors": errors,
        "tagged": by_kind["plan"] // args.tag_every if args.tag_every else 0,
        "catalog_bytes": catalog_bytes,
        "catalog_bytes_per_row": round(catalog_bytes / rows, 1),
        "template_s": round(template_s, 2),
        "create_s_per_run": round(create_s, 5),
        "build_s_per_run": round(build_s / runs, 5),
        "rebuild_s": round(rebuild_s, 3),
        "refresh_unchanged_s": round(unchanged_s, 3),
        "refresh_one_new_run_s": round(new_run_s, 3),
        "read_s": round(read_s, 4),
        "query_plans_s": round(query_s["plans"], 4),
        "query_runs_s": round(query_s["runs"], 4),
        "query_plans_rows": matched["plans"],
        "query_runs_rows": matched["runs"],
        "where": where,
        "cli_startup_s": round(startup_s, 3),
        "runs_command_empty_store_s": round(empty_s, 3),
        "runs_command_s": round(runs_s, 3),
        "runs_command_lines": runs_lines,
        "runs_where_command_s": round(where_s, 3),
        "runs_where_command_lines": where_lines,
        "repeats": args.repeats,
        "fast_repeats": FAST_REPEATS,
        "goals": {"query_s_max": QUERY_GOAL_S, "runs_command_s_max": RUNS_COMMAND_GOAL_S},
        "ratios": ratios,
        "met": {
            "query": max(query_s.values()) <= QUERY_GOAL_S,
            "runs_command": max(runs_s, where_s) <= RUNS_COMMAND_GOAL_S,
        },
    }
    if not args.json:
        _table(figures)
    print(json.dumps(figures))


def _table(f: dict) -> None:
    kinds = ", ".join(f"{n:,} {k}" for k, n in f["rows_by_kind"].items() if n)
    print(
        f"catalog of a synthetic store: {f['runs']:,} runs in {f['families']:,} families over "
        f"{f['nights']} nights ({kinds}; {f['tagged']} tagged)"
    )
    print(
        f"  catalog.parquet {f['catalog_bytes']:,} bytes, {f['catalog_bytes_per_row']} per row; "
        f"rows in error {f['row_errors']}"
    )
    print(
        f"  store made in {f['build_s_per_run'] * 1e3:.2f} ms a run (RunStore.create "
        f"{f['create_s_per_run'] * 1e3:.1f} ms a run; template {f['template_s']} s)"
    )
    print(f"  {'(medians)':44}{'seconds':>10}{'goal':>8}{'ratio':>8}")
    ratios = f["ratios"]
    goal_q, goal_c = f["goals"]["query_s_max"], f["goals"]["runs_command_s_max"]
    rows = (
        (f"refresh, rebuild (x{f['repeats']})", f["rebuild_s"], None, None),
        (f"refresh, nothing changed (x{f['fast_repeats']})", f["refresh_unchanged_s"], None, None),
        ("refresh after one new run", f["refresh_one_new_run_s"], None, None),
        ("read the catalog file", f["read_s"], None, None),
        (f"query plans ({f['query_plans_rows']} rows)", f["query_plans_s"], goal_q, "query_plans"),
        (f"query runs ({f['query_runs_rows']} rows)", f["query_runs_s"], goal_q, "query_runs"),
        ("ovtraj --help (start-up)", f["cli_startup_s"], None, None),
        ("ovtraj runs, an empty store", f["runs_command_empty_store_s"], None, None),
        ("ovtraj runs", f["runs_command_s"], goal_c, "runs_command"),
        ("ovtraj runs --where <plans>", f["runs_where_command_s"], goal_c, "runs_where_command"),
    )
    for label, seconds, goal, ratio in rows:
        tail = f"{goal:>8g}{ratios[ratio]:>8.3f}" if goal else ""
        print(f"  {label:44}{seconds:>10.4f}{tail}")
    for name, where in f["where"].items():
        print(f"  where {name}: {where}")
    print(f"  goals met: query {f['met']['query']}, ovtraj runs {f['met']['runs_command']}")


if __name__ == "__main__":
    main()
