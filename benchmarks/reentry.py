"""Reentry stage: time of one guided solve after warm-up, and trajectories integrated.

The default scenario's entry (the deorbit stage's default entry state) is guided to
Kennedy's runway: golden-section search on the terminal bank with Newton on the
entry bank inside. The first solve compiles (or loads from numba's cache) the
entry dynamics; then repeated solves are timed in this process. Goal: one guided
solve under 200 ms after warm-up.

Run: ``python benchmarks/reentry.py [--json]``: a table, then one JSON object with the
figures, the goal and the ratio as the last line (``--json``: only that).
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

from goals import goal

from ovtraj.reentry import reentry_input, solve_reentry
from ovtraj.reentry.model import EntryModel
from ovtraj.target_sources import load_scenario

ROOT = Path(__file__).resolve().parents[1]
REPEATS = 10
GOAL_S = goal("reentry", "solve_s")  # the entry guidance's speed goal [s] after warm-up


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print only the JSON object")
    args = parser.parse_args()
    say = (lambda *_: None) if args.json else print
    scenario = load_scenario(ROOT / "configs" / "scenario.yaml")
    inp = reentry_input(scenario)
    start = time.perf_counter()
    solve_reentry(inp)
    warm_up = time.perf_counter() - start
    times = []
    for _ in range(REPEATS):
        start = time.perf_counter()
        result = solve_reentry(inp)
        times.append(time.perf_counter() - start)
    solve_time = statistics.median(times)
    model = EntryModel(inp)
    flight_times = []
    for _ in range(REPEATS):
        start = time.perf_counter()
        model.fly(result.sigma0_rad, result.sigma1_rad)
        flight_times.append(time.perf_counter() - start)
    row = result.to_row()
    say(f"reentry benchmark ({scenario.name}), median of {REPEATS} runs after warm-up")
    say(f"  first solve (compile or cache load)  {warm_up:8.3f} s")
    say(
        f"  one guided solve                     {1e3 * solve_time:8.1f} ms   goal "
        f"{1e3 * GOAL_S:.0f} ms   ratio {solve_time / GOAL_S:.2f}"
    )
    say(f"  trajectories per solve               {row['trajectories']:8d}")
    say(
        f"  one trajectory ({row['flight_time_s']:.0f} s of flight)      "
        f"{1e3 * statistics.median(flight_times):8.2f} ms"
    )
    say(
        f"  result: miss {row['miss_distance_km']:.3f} km, terminal "
        f"{row['terminal_altitude_km']:.2f} km / {row['terminal_speed_mps']:.0f} m/s, max heat "
        f"{row['max_heat_rate_kw_m2']:.0f} kW/m^2, load {row['max_load_g']:.2f} g, q "
        f"{row['max_dynamic_pressure_kpa']:.1f} kPa, feasible {row['feasible']}"
    )
    result_keys = (
        "miss_distance_km",
        "terminal_altitude_km",
        "terminal_speed_mps",
        "max_heat_rate_kw_m2",
        "max_load_g",
        "max_dynamic_pressure_kpa",
    )
    figures = {
        "repeats": REPEATS,
        "warm_up_s": round(warm_up, 4),
        "solve_s": round(solve_time, 5),
        "trajectories": int(row["trajectories"]),
        "trajectory_s": round(statistics.median(flight_times), 6),
        "flight_time_s": float(row["flight_time_s"]),
        "result": {k: float(row[k]) for k in result_keys} | {"feasible": bool(row["feasible"])},
        "goal_s": GOAL_S,
        "ratio": round(solve_time / GOAL_S, 3),
        "met": solve_time <= GOAL_S,
    }
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
