"""The main job's answer: does the default run converge, is its front right, is the chain smooth?

Two measurements on the shipped scenario, side by side in this process and its pool:

1. **Convergence against the direct reference.** The default pipeline (the scenario's DoE
   size, surrogate, optimisation and verification settings: what ``ovtraj pipeline``
   runs) once per DoE seed, on one pool of ``--workers`` spawned processes (started before
   the first pipeline, counted in no pipeline's time). Per seed: real evaluations, rounds,
   whether it converged and why it stopped, what the last surrogates still promised, the
   verified front's hypervolume and its ratio to the stored direct reference front's
   (``data/reference/direct_front``, NSGA-II with 6,000 real evaluations;
   ``tools/direct_reference.py``).
2. **No cliffs.** ``--cliff-designs`` random designs of the design space (seeded), each
   design variable moved by a small step (H_P0 and H_dp +50 m, t_dsp +0.05 h): the share of
   the pairs (both feasible) whose dV_total moves by less than 1 m/s, and every larger move
   with whether T_total moved by a whole pass with it (over 12 h: passes are a day or more
   apart).

Goals: at least 19 of 20 seeds converge; every converged front >= 0.99 of the reference's
hypervolume and the worst seed >= 0.985; median real evaluations <= 60 (1 % of the
reference's); >= 98 % of the pairs under 1 m/s and every larger move with a pass change.

Run: ``python benchmarks/convergence.py [--seeds 2026 ... 2045] [--workers 2]
[--cliff-designs 200] [--config FILE] [--keep-stores DIR] [--json]``; ``--json`` prints only
the JSON object (otherwise the tables, then that object as the last line). About 15 min
here on 2 cores.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from goals import goals  # noqa: E402
from surrogate_vs_direct import pipeline, ready_pool  # noqa: E402

SEEDS = list(range(2026, 2046))
GOALS = goals("convergence")
# The design steps of the cliff probe: H_P0 and H_dp [km], t_dsp [h].
STEPS = (0.05, 0.05, 0.05)
SMOOTH_DV_MPS = 1.0  # a pair's dV_total moves by less than this
PASS_STEP_H = 12.0  # a T_total move this large is another pass (passes are >= a day apart)


def _pair(design: tuple[float, float, float]) -> list[tuple[bool, float, float]]:
    """The design and each of its three stepped neighbours: (feasible, dV_total, T_total)."""
    from surrogate_vs_direct import _evaluate

    out = []
    for k in range(4):
        moved = list(design)
        if k:
            moved[k - 1] += STEPS[k - 1]
        feasible, t_total, dv_total, _ = _evaluate(tuple(moved))
        out.append((feasible, dv_total, t_total))
    return out


def cliffs(scenario, pool, designs: int, seed: int) -> dict:
    from ovtraj.mission.design_space import bounds_arrays

    lower, upper = bounds_arrays(scenario.mission.design_bounds)
    rng = np.random.default_rng(seed)
    points = lower + rng.random((designs, 3)) * (upper - lower - np.array(STEPS))
    pairs, large = 0, []
    for design, results in zip(
        points, pool.map(_pair, [tuple(map(float, p)) for p in points]), strict=True
    ):
        base = results[0]
        for k, moved in enumerate(results[1:]):
            if not (base[0] and moved[0]):
                continue
            pairs += 1
            change = abs(moved[1] - base[1])
            if change >= SMOOTH_DV_MPS:
                large.append(
                    {
                        "design": [round(float(v), 4) for v in design],
                        "moved": ("H_P0", "H_dp", "t_dsp")[k],
                        "dv_change_mps": round(change, 3),
                        "t_change_h": round(abs(moved[2] - base[2]) / 3600.0, 3),
                    }
                )
    with_pass = sum(1 for c in large if c["t_change_h"] >= PASS_STEP_H)
    return {
        "designs": designs,
        "feasible_pairs": pairs,
        "smooth_share": (pairs - len(large)) / pairs if pairs else None,
        "large_changes": large,
        "large_without_pass_change": len(large) - with_pass,
    }


def main() -> None:
    from ovtraj.launch.launch_fit import find_launch_fit
    from ovtraj.pipeline.reference_front import reference_for
    from ovtraj.target_sources import load_scenario

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=SEEDS)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--cliff-designs", type=int, default=200)
    parser.add_argument("--cliff-seed", type=int, default=56)
    parser.add_argument("--config", type=Path, default=ROOT / "configs" / "scenario.yaml")
    parser.add_argument("--keep-stores", type=Path, default=None)
    parser.add_argument("--json", action="store_true", help="print only the JSON object")
    args = parser.parse_args()
    say = (lambda *_: None) if args.json else print

    scenario = load_scenario(args.config)
    reference = reference_for(scenario)
    if reference is None:
        raise SystemExit(
            f"{args.config}: no direct reference front for this scenario "
            "(python tools/direct_reference.py stores one)"
        )
    fit = find_launch_fit(scenario)
    samples = scenario.mission.doe.samples
    keep = None if args.keep_stores is None else args.keep_stores.resolve()
    pool, started = ready_pool(args.workers)
    with pool:
        rows = [
            pipeline(scenario, fit, seed, samples, pool, args.workers, keep) for seed in args.seeds
        ]
        smooth = cliffs(scenario, pool, args.cliff_designs, args.cliff_seed)
    say(
        f"default pipeline ({samples}-sample DoE, shipped settings) on {len(rows)} DoE seeds; "
        f"direct reference: {reference.meta['evaluations']:,} evaluations, hypervolume "
        f"{reference.hypervolume:.4f} ({reference.meta['command']})"
    )
    say(f"{'seed':>6}{'evals':>7}{'rounds':>8}{'hypervolume':>13}{'ratio':>8}{'promise':>9}  stop")
    for r in rows:
        promise = "-" if r["promised_gain"] is None else f"{r['promised_gain']:.2%}"
        say(
            f"{r['seed']:>6}{r['evaluations']:>7}{r['rounds']:>8}{r['hypervolume']:>13.4f}"
            f"{r['reference_ratio']:>8.4f}{promise:>9}  {r['stop']}"
        )
    converged = [r for r in rows if r["converged"]]
    ratios = [r["reference_ratio"] for r in rows]
    figures = {
        "seeds": len(rows),
        "converged": len(converged),
        "converged_ratio_min": min((r["reference_ratio"] for r in converged), default=None),
        "worst_ratio": min(ratios),
        "median_ratio": statistics.median(ratios),
        "median_evaluations": statistics.median(r["evaluations"] for r in rows),
        "max_evaluations": max(r["evaluations"] for r in rows),
        "reference_hypervolume": reference.hypervolume,
        "reference_evaluations": int(reference.meta["evaluations"]),
        "smooth_share": smooth["smooth_share"],
        "large_without_pass_change": smooth["large_without_pass_change"],
        "cliff_probe": smooth,
        "runs": rows,
        "pool_start_s": started,
        "goals": GOALS,
    }
    figures["met"] = {
        "converged": figures["converged"] >= GOALS["converged_min"],
        "converged_ratio": (figures["converged_ratio_min"] or 0.0) >= GOALS["converged_ratio_min"],
        "worst_ratio": figures["worst_ratio"] >= GOALS["worst_ratio_min"],
        "median_evaluations": figures["median_evaluations"] <= GOALS["median_evaluations_max"],
        "smooth": (smooth["smooth_share"] or 0.0) >= GOALS["smooth_pairs_min"]
        and smooth["large_without_pass_change"] == 0,
    }
    figures["ratios"] = {
        "converged": figures["converged"] / GOALS["converged_min"],
        "converged_ratio": (figures["converged_ratio_min"] or 0.0) / GOALS["converged_ratio_min"],
        "worst_ratio": figures["worst_ratio"] / GOALS["worst_ratio_min"],
        "median_evaluations": figures["median_evaluations"] / GOALS["median_evaluations_max"],
        "smooth": (smooth["smooth_share"] or 0.0) / GOALS["smooth_pairs_min"],
    }
    say(
        f"converged {figures['converged']} of {len(rows)} (goal >= {GOALS['converged_min']}), "
        f"worst converged ratio {figures['converged_ratio_min']}, worst ratio "
        f"{figures['worst_ratio']:.4f}, median evaluations {figures['median_evaluations']}"
    )
    share = "-" if smooth["smooth_share"] is None else f"{smooth['smooth_share']:.2%}"
    say(
        f"cliff probe: {smooth['designs']} designs, {smooth['feasible_pairs']} feasible pairs, "
        f"{share} under {SMOOTH_DV_MPS:g} m/s; "
        f"{len(smooth['large_changes'])} larger, {smooth['large_without_pass_change']} without a "
        "pass change"
    )
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
