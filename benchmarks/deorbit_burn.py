"""Finite-thrust deorbit burn (seed 004): one converged solve, the burn-angle study, and a
200-run Monte Carlo with 2 workers, printed next to the seed's published figures.

1. One solve of the published case (``configs/cases/shuttle_deorbit.yaml``): the first
   (cold: heyoka compiles its integrators) and the median of repeated solves after warm-up.
2. The burn-angle study over the config's angles: delta-v at 0 and +-27 deg, the entry
   speed error, and the angles where it crosses zero.
3. The Monte Carlo flow (``flows/deorbit_monte_carlo.py``) under a temporary Prefect server,
   2 worker processes, into a fresh store: its wall time, the time per simulated run
   (measured inside the tasks), and the dispersion statistics per strategy.

Run: ``python benchmarks/deorbit_burn.py [runs] [workers] [--repeats 7] [--json]``
(default 200 runs, 2 workers; ``--repeats``: the timed solves of part 1): the tables, then
one JSON object with the figures and the published comparison as the last line
(``--json``: only that).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import yaml

os.environ.setdefault("PREFECT_SERVER_ANALYTICS_ENABLED", "false")

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # flows/ (the Monte Carlo flow), as from the checkout
CASE = ROOT / "configs" / "cases" / "shuttle_deorbit.yaml"
REPEATS = 7


def main() -> None:
    from ovtraj.studies.deorbit_burn import (
        burn_angle_study,
        load_deorbit_burn,
        monte_carlo_summary,
        solve_deorbit_burn,
        zero_speed_error_angles,
    )
    from ovtraj.studies.deorbit_burn.published import format_comparison, published_comparison
    from ovtraj.studies.deorbit_burn.store import MonteCarloRun

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", type=int, nargs="?", default=200)
    parser.add_argument("workers", type=int, nargs="?", default=2)
    parser.add_argument("--repeats", type=int, default=REPEATS)
    parser.add_argument("--json", action="store_true", help="print only the JSON object")
    args = parser.parse_args()
    say = (lambda *_: None) if args.json else print
    runs, workers, repeats = args.runs, args.workers, args.repeats
    problem = load_deorbit_burn(CASE)

    start = time.perf_counter()
    result = solve_deorbit_burn(problem)
    cold = time.perf_counter() - start
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        result = solve_deorbit_burn(problem)
        times.append(time.perf_counter() - start)
    say(f"Deorbit burn benchmark: {problem.name}")
    say(
        f"  one converged solve            {statistics.median(times) * 1e3:8.1f} ms median of "
        f"{repeats} (cold, with integrator compilation: {cold:.2f} s)"
    )
    say(
        f"    {result.iterations} iterations, u_open {result.u_open_deg:.4f} deg, dv "
        f"{result.dv_mps:.3f} m/s, burn {result.burn_duration_s:.1f} s at "
        f"{result.burn_angle_deg:.2f} deg; entry errors u {result.entry_u_error_deg:.2e} deg, "
        f"fpa {result.entry_fpa_error_deg:.2e} deg, speed {result.entry_speed_error_mps:.3f} m/s"
    )
    for record in result.history:
        say(
            f"    iteration {record.iteration}: u_open {record.u_open_deg:.5f} deg, dv "
            f"{record.dv_mps:.3f} m/s, entry u error {record.entry_u_error_deg:+.5f} deg "
            f"({record.along_track_error_km:+.3f} km), speed error "
            f"{record.entry_speed_error_mps:+.3f} m/s"
        )

    start = time.perf_counter()
    study = burn_angle_study(problem)
    study_time = time.perf_counter() - start
    say(f"  burn-angle study               {study_time:8.2f} s for {len(study)} angles")
    for row in study.itertuples():
        say(
            f"    {row.burn_angle_deg:+6.1f} deg: dv {row.dv_mps:8.3f} m/s, speed error "
            f"{row.entry_speed_error_mps:+7.3f} m/s, {row.iterations} iterations"
        )
    zero_angles = zero_speed_error_angles(study)
    say(f"    entry speed error crosses zero at {zero_angles} deg")

    from prefect.testing.utilities import prefect_test_harness

    from flows.deorbit_monte_carlo import deorbit_monte_carlo_flow

    workdir = Path(tempfile.mkdtemp(prefix="ovtraj-deorbit-mc-"))
    data = yaml.safe_load(CASE.read_text(encoding="utf-8"))
    data["monte_carlo"].update(
        runs=runs, workers=workers, task_runner="processes", store=str(workdir)
    )
    config = workdir / "case.yaml"
    config.write_text(yaml.safe_dump(data), encoding="utf-8")
    with prefect_test_harness(server_startup_timeout=60):
        # Worker processes inherit the environment, not the harness's settings context:
        # point them at this server instead of letting each start its own.
        from prefect.settings import PREFECT_API_URL

        os.environ["PREFECT_API_URL"] = PREFECT_API_URL.value()
        start = time.perf_counter()
        report = deorbit_monte_carlo_flow(str(config))
        wall = time.perf_counter() - start
    stored = MonteCarloRun(Path(report["directory"]))
    frame, timing = stored.results(), stored.timing()
    per_run = timing.groupby("run")["wall_time_s"].max().to_numpy()
    busy = float(per_run.sum()) / workers
    say(
        f"  Monte Carlo flow, {runs} runs x {len(report['strategies'])} strategies, {workers} "
        f"worker processes, batches of {data['monte_carlo']['batch_size']}"
    )
    say(f"    flow wall time               {wall:8.1f} s")
    say(
        f"    one run (plan + flights)     {statistics.median(per_run) * 1e3:8.1f} ms median; "
        f"summed {per_run.sum():.1f} s; orchestration and start-up "
        f"{100 * max(wall - busy, 0.0) / wall:.0f} % of the wall time"
    )
    summary = monte_carlo_summary(frame)
    for row in summary.itertuples():
        say(
            f"    strategy {row.strategy}: {row.runs} runs, {row.failed} failed; along-track "
            f"max |err| {row.along_track_error_km_max_abs:.3f} km (std "
            f"{row.along_track_error_km_std:.3f}); fpa max |err| "
            f"{row.entry_fpa_error_deg_max_abs:.2e} deg (std {row.entry_fpa_error_deg_std:.1e}); "
            f"dv {row.dv_mps_min:.1f}-{row.dv_mps_max:.1f} m/s"
        )
    say(f"    run directory {report['directory']}")
    say("  Published (seed 004) vs ours")
    comparison = published_comparison(problem, result=result, study=study, summary=summary)
    say(format_comparison(comparison))
    figures = {
        "case": problem.name,
        "solve_s": round(statistics.median(times), 5),
        "cold_solve_s": round(cold, 3),
        "repeats": repeats,
        "iterations": int(result.iterations),
        "dv_mps": float(result.dv_mps),
        "burn_angle_study_s": round(study_time, 3),
        "burn_angles": len(study),
        "zero_speed_error_angles_deg": [float(a) for a in zero_angles],
        "monte_carlo": {
            "runs": runs,
            "workers": workers,
            "strategies": len(report["strategies"]),
            "wall_s": round(wall, 2),
            "run_median_s": round(float(statistics.median(per_run)), 4),
            "orchestration_fraction": round(max(wall - busy, 0.0) / wall, 3),
        },
        # The seed's published figures are this benchmark's goals: each row's verdict.
        "published": [row.as_dict() for row in comparison],
        "met": all(row.matches is not False for row in comparison),
    }
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
