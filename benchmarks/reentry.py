"""Reentry stage: time of one guided solve after warm-up, and trajectories integrated.

The default scenario's entry (the deorbit stage's default entry state) is guided to
Kennedy's runway: golden-section search on the terminal bank with Newton on the
entry bank inside. The first solve compiles (or loads from numba's cache) the
entry dynamics; then repeated solves are timed in this process. Goal (issue 5):
one guided solve under 200 ms after warm-up.

Run: ``python benchmarks/reentry.py``.
"""

from __future__ import annotations

import statistics
import time
from pathlib import Path

from ovtraj.config import load_scenario
from ovtraj.reentry import reentry_input, solve_reentry
from ovtraj.reentry.model import EntryModel

ROOT = Path(__file__).resolve().parents[1]
REPEATS = 10
GOAL_S = 0.200  # issue 5: under 200 ms after warm-up


def main() -> None:
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
    print(f"reentry benchmark ({scenario.name}), median of {REPEATS} runs after warm-up")
    print(f"  first solve (compile or cache load)  {warm_up:8.3f} s")
    print(
        f"  one guided solve                     {1e3 * solve_time:8.1f} ms   goal "
        f"{1e3 * GOAL_S:.0f} ms   ratio {solve_time / GOAL_S:.2f}"
    )
    print(f"  trajectories per solve               {row['trajectories']:8d}")
    print(
        f"  one trajectory ({row['flight_time_s']:.0f} s of flight)      "
        f"{1e3 * statistics.median(flight_times):8.2f} ms"
    )
    print(
        f"  result: miss {row['miss_distance_km']:.3f} km, terminal "
        f"{row['terminal_altitude_km']:.2f} km / {row['terminal_speed_mps']:.0f} m/s, max heat "
        f"{row['max_heat_rate_kw_m2']:.0f} kW/m^2, load {row['max_load_g']:.2f} g, q "
        f"{row['max_dynamic_pressure_kpa']:.1f} kPa, feasible {row['feasible']}"
    )


if __name__ == "__main__":
    main()
