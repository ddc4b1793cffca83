"""The same pipeline under other OpenBLAS kernels and thread counts: the same bytes?

The default pipeline (``ovtraj pipeline configs/scenario.yaml``, shipped defaults) run in
processes of their own, each with a workspace and run store of its own (``OVTRAJ_HOME``),
under ``OPENBLAS_CORETYPE`` unset (the machine's own kernel), Haswell and Sandybridge,
each with ``OPENBLAS_NUM_THREADS`` 1 and 2. ovtraj pins OpenBLAS's kernel before numpy
loads (ovtraj/environment.py), so every variant must store the same files: the verified
front (``front.parquet``), the plan JSON and every Parquet file of every DoE and infill
run are compared byte for byte with the first variant's. ``--unpinned`` runs the same
variants with the pin switched off (``OVTRAJ_BLAS_KERNEL=native``): what the pin prevents.

Goal: byte-identical files in every variant (``identical_variants`` = all of them). Each
variant runs the code of the checkout when it starts: run it on a checkout nobody edits
meanwhile (the table says when the variants ran other code versions).

Run: ``python benchmarks/reproducibility.py [--samples N] [--config FILE] [--variants
native:1,Haswell:2] [--parallel 2] [--unpinned] [--json]``: ``--json`` prints only the JSON
object (otherwise the table, then that object as the last line). Each pipeline takes
~40-60 s here with the shipped settings; ``--parallel`` runs that many at once.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OVTRAJ = str(Path(sys.executable).with_name("ovtraj"))
NATIVE = "native"
VARIANTS = "native:1,native:2,Haswell:1,Haswell:2,Sandybridge:1,Sandybridge:2"
# What a DoE or infill run stores as data (its markers hold times and the environment).
DOE_DATA = ("samples.parquet", "stages", "totals", "trajectories")


def _arguments() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--config", default=str(ROOT / "configs" / "scenario.yaml"))
    parser.add_argument("--samples", type=int, default=None, help="default: the scenario's")
    parser.add_argument(
        "--variants",
        default=VARIANTS,
        help="KERNEL:THREADS,... (KERNEL: an OPENBLAS_CORETYPE, or native: unset)",
    )
    parser.add_argument("--parallel", type=int, default=2, help="pipelines run at once")
    parser.add_argument("--unpinned", action="store_true", help="OVTRAJ_BLAS_KERNEL=native: no pin")
    parser.add_argument("--json", action="store_true", help="print only the JSON object")
    return parser.parse_args()


def _variants(text: str) -> list[tuple[str, int]]:
    found = []
    for item in text.split(","):
        kernel, _, threads = item.strip().partition(":")
        found.append((kernel, int(threads or 1)))
    return found


def _pipeline(folder: Path, kernel: str, threads: int, args: argparse.Namespace) -> dict:
    """One pipeline in a process and a workspace of its own; its JSON summary, its
    files and its wall time."""
    drop = ("OVTRAJ_", "OPENBLAS_", "PREFECT_")
    env = {k: v for k, v in os.environ.items() if not k.startswith(drop)}
    env |= {"OVTRAJ_HOME": str(folder), "OPENBLAS_NUM_THREADS": str(threads)}
    env["OVTRAJ_DEBUG"] = "1"  # a fault's traceback in the message below
    if kernel != NATIVE:
        env["OPENBLAS_CORETYPE"] = kernel
    if args.unpinned:
        env["OVTRAJ_BLAS_KERNEL"] = NATIVE
    command = [OVTRAJ, "-q", "pipeline", args.config, "--json"]
    if args.samples is not None:
        command += ["--samples", str(args.samples)]
    start = time.perf_counter()
    done = subprocess.run(
        command, env=env, cwd=ROOT, capture_output=True, text=True, timeout=3600, check=False
    )
    wall = time.perf_counter() - start
    if done.returncode not in (0, 1) or not done.stdout.strip():  # 1: not converged
        raise SystemExit(f"{kernel}:{threads}: exit {done.returncode}\n{done.stderr[-3000:]}")
    summary = json.loads(done.stdout)
    plan = Path(summary["plan_json"])
    runs = folder / "runs"
    files = {
        f"plan/{plan.name}": plan.read_bytes(),
        "front.parquet": Path(summary["front"]).read_bytes(),
    }
    for path in sorted(runs.glob("*/*")):
        if path.name in DOE_DATA:
            for part in [path] if path.is_file() else sorted(path.rglob("*.parquet")):
                files[str(part.relative_to(runs))] = part.read_bytes()
    picked = json.loads(plan.read_text())["source"]["sample_id"]
    manifest = json.loads((runs / summary["doe_run"] / "manifest.json").read_text())
    return {
        "summary": summary,
        "files": files,
        "wall_s": wall,
        "sample_id": picked,
        "code_version": manifest["code_version"],
    }


def main() -> None:
    args = _arguments()
    say = (lambda *_: None) if args.json else print
    variants = _variants(args.variants)
    with (
        tempfile.TemporaryDirectory(prefix="ovtraj-reproducibility-") as tmp,
        ThreadPoolExecutor(max(1, args.parallel)) as pool,
    ):
        futures = [
            pool.submit(_pipeline, Path(tmp) / f"{kernel}-{threads}", kernel, threads, args)
            for kernel, threads in variants
        ]
        results = [future.result() for future in futures]
    first = results[0]["files"]
    rows = []
    for (kernel, threads), result in zip(variants, results, strict=True):
        files = result["files"]
        same = sum(1 for name, data in files.items() if first.get(name) == data)
        identical = same == len(files) == len(first)
        summary = result["summary"]
        rows.append(
            {
                "openblas_coretype": None if kernel == NATIVE else kernel,
                "openblas_threads": threads,
                "pipeline_id": summary["pipeline_id"],
                "doe_run": summary["doe_run"],
                "code_version": result["code_version"],
                "picked_sample": result["sample_id"],
                "hypervolume": summary["hypervolume"],
                "files": len(files),
                "files_identical": same,
                "identical": identical,
                "differing": sorted(n for n, d in files.items() if first.get(n) != d)[:5],
                "wall_s": round(result["wall_s"], 1),
            }
        )
    identical = sum(row["identical"] for row in rows)
    report = {
        "config": args.config,
        "samples": args.samples,
        "pinned": not args.unpinned,
        "variants": rows,
        "figures": {
            "variants": len(rows),
            "identical_variants": identical,
            "pipeline_ids": len({row["pipeline_id"] for row in rows}),
            "code_versions": len({row["code_version"] for row in rows}),
            "picked_samples": sorted({row["picked_sample"] for row in rows}),
            "hypervolumes": sorted({row["hypervolume"] for row in rows}),
        },
        "goals": {"byte_identical": "all", "identical_variants": len(rows)},
        "ratios": {"identical_variants": round(identical / len(rows), 3)},
        "met": identical == len(rows),
    }
    pin = "pinned by ovtraj" if not args.unpinned else "unpinned (OVTRAJ_BLAS_KERNEL=native)"
    say(
        f"The pipeline of {args.config} ({args.samples or 'default'} samples) in "
        f"{len(rows)} processes, each with its own store, OpenBLAS {pin}; every variant's "
        "front.parquet, plan JSON and DoE Parquet files compared byte for byte with the first"
    )
    say(
        f"  {'OPENBLAS_CORETYPE':18}{'threads':>8}  {'pipeline id':17}{'sample':>7}"
        f"{'hypervolume':>13}{'identical files':>17}{'wall [s]':>10}"
    )
    for row in rows:
        say(
            f"  {row['openblas_coretype'] or '(unset)':18}{row['openblas_threads']:8d}  "
            f"{row['pipeline_id']:17}{row['picked_sample']:7d}{row['hypervolume']:13.5f}"
            f"{str(row['files_identical']) + '/' + str(row['files']):>17}{row['wall_s']:10.1f}"
        )
    if report["figures"]["code_versions"] > 1:
        # the run ids hold the code version: files of other code are other runs, not a
        # reproducibility result (a checkout edited while the benchmark ran)
        say("  the code changed while the variants ran: run it on a checkout nobody edits")
    verdict = "met" if report["met"] else "NOT met"
    say(f"  byte-identical variants: {identical} of {len(rows)} (goal: all, {verdict})")
    print(json.dumps(report))


if __name__ == "__main__":
    main()
