"""Our figures next to the seed's published ones (the ``published`` section of the config).

Figures (seed sec. 2.4, 2.5 and 4): iterations to the u tolerance; delta-v at burn angle 0
and at +-27 deg; how much the entry speed rises from angle 0 to +-27 deg; the angle that
nulls the entry speed error; the strategy 1 along-track and strategy 2 flight-path-angle
dispersions (largest absolute error over the runs) and the strategy 2 along-track spread.
``matches`` is None for figures given for information (no bound printed in the seed).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import pandas as pd

from ovtraj.studies.deorbit_burn.problem import DeorbitBurnProblem
from ovtraj.studies.deorbit_burn.result import DeorbitBurnResult
from ovtraj.studies.deorbit_burn.study import zero_speed_error_angles

__all__ = ["Comparison", "format_comparison", "published_comparison"]


@dataclass(frozen=True)
class Comparison:
    figure: str
    unit: str
    published: str  # as the seed prints it ("5", "~88", "< 3.5")
    ours: float
    matches: bool | None

    def as_dict(self) -> dict[str, Any]:
        row = asdict(self)
        row["ours"] = None if not math.isfinite(self.ours) else self.ours
        return row


def _study_value(study: pd.DataFrame | None, angle: float, column: str) -> float:
    if study is None:
        return math.nan
    rows = study[(study["burn_angle_deg"] - angle).abs() < 1e-9]
    rows = rows[rows["converged"]]
    return float(rows[column].iloc[0]) if len(rows) else math.nan


def _strategy_value(summary: pd.DataFrame | None, strategy: int, column: str) -> float:
    if summary is None or not len(summary):
        return math.nan
    rows = summary[summary["strategy"] == strategy]
    return float(rows[column].iloc[0]) if len(rows) else math.nan


def published_comparison(
    problem: DeorbitBurnProblem,
    *,
    result: DeorbitBurnResult | None = None,
    study: pd.DataFrame | None = None,
    summary: pd.DataFrame | None = None,
) -> list[Comparison]:
    """The comparison rows that the given pieces allow (NaN where a piece is missing).

    ``result``: a converged solve (iterations); ``study``: :func:`burn_angle_study` with the
    angles 0 and +-``zero_speed_error_burn_angle_deg``; ``summary``:
    :func:`monte_carlo_summary`.
    """
    return [
        _iterations_row(problem, result),
        *_burn_angle_rows(problem, study),
        *_dispersion_rows(problem, summary),
    ]


def _iterations_row(problem: DeorbitBurnProblem, result: DeorbitBurnResult | None) -> Comparison:
    """Iterations of a converged solve to the u tolerance (seed sec. 2.4)."""
    pub = problem.config.published
    iterations = math.nan if result is None or not result.converged else float(result.iterations)
    return Comparison(
        f"iterations to {problem.config.guidance.u_tolerance_deg:g} deg",
        "",
        f"{pub.iterations}",
        iterations,
        None if math.isnan(iterations) else iterations <= pub.iterations,
    )


def _burn_angle_rows(problem: DeorbitBurnProblem, study: pd.DataFrame | None) -> list[Comparison]:
    """The burn-angle study's figures (seed sec. 2.5): delta-v at angle 0 and at
    +-the published angle, the rise of the entry speed error between them, the angle
    that nulls it."""
    pub = problem.config.published
    tol = pub.approximate_tolerance_mps
    angle = pub.zero_speed_error_burn_angle_deg
    rows = []
    dv0 = _study_value(study, 0.0, "dv_mps")
    rows.append(
        Comparison(
            "delta-v at burn angle 0",
            "m/s",
            f"~{pub.dv_burn_angle_0_mps:g}",
            dv0,
            None if math.isnan(dv0) else abs(dv0 - pub.dv_burn_angle_0_mps) <= tol,
        )
    )
    speed_errors = []
    for signed in (-angle, angle):
        dv = _study_value(study, signed, "dv_mps")
        speed_errors.append(_study_value(study, signed, "entry_speed_error_mps"))
        rows.append(
            Comparison(
                f"delta-v at burn angle {signed:+g} deg",
                "m/s",
                f"~{pub.dv_burn_angle_27_mps:g}",
                dv,
                None if math.isnan(dv) else abs(dv - pub.dv_burn_angle_27_mps) <= tol,
            )
        )
    rise = sum(speed_errors) / 2.0 - _study_value(study, 0.0, "entry_speed_error_mps")
    rows.append(
        Comparison(
            f"entry speed error at +-{angle:g} deg minus at 0 deg",
            "m/s",
            f"{pub.speed_error_increase_mps:g}",
            rise,
            None if math.isnan(rise) else abs(rise - pub.speed_error_increase_mps) <= tol,
        )
    )
    zeros = [] if study is None else zero_speed_error_angles(study)
    rows.append(
        Comparison(
            "burn angle nulling the entry speed error (mean |angle|)",
            "deg",
            f"+-{angle:g}",
            sum(abs(z) for z in zeros) / len(zeros) if zeros else math.nan,
            None,
        )
    )
    return rows


def _dispersion_rows(problem: DeorbitBurnProblem, summary: pd.DataFrame | None) -> list[Comparison]:
    """The Monte Carlo dispersions of both strategies (seed sec. 4)."""
    pub = problem.config.published
    along1 = _strategy_value(summary, 1, "along_track_error_km_max_abs")
    fpa2 = _strategy_value(summary, 2, "entry_fpa_error_deg_max_abs")
    return [
        Comparison(
            "strategy 1: largest along-track entry error",
            "km",
            f"< {pub.strategy1_along_track_km:g}",
            along1,
            None if math.isnan(along1) else along1 < pub.strategy1_along_track_km,
        ),
        Comparison(
            "strategy 2: largest entry flight-path-angle error",
            "deg",
            f"<= {pub.strategy2_fpa_deg:g}",
            fpa2,
            None if math.isnan(fpa2) else fpa2 <= pub.strategy2_fpa_deg,
        ),
        Comparison(
            "strategy 2: largest along-track entry error",
            "km",
            f"up to {pub.strategy2_along_track_km:g}",
            _strategy_value(summary, 2, "along_track_error_km_max_abs"),
            None,
        ),
    ]


def format_comparison(rows: list[Comparison]) -> str:
    """A plain-text table: figure, published, ours, verdict."""
    lines = [f"  {'figure':58s} {'published':>12s} {'ours':>12s}  verdict"]
    for row in rows:
        ours = "n/a" if not math.isfinite(row.ours) else f"{row.ours:.6g}"
        verdict = {True: "match/beat", False: "differs", None: "(information)"}[row.matches]
        figure = f"{row.figure} [{row.unit}]" if row.unit else row.figure
        lines.append(f"  {figure:58s} {row.published:>12s} {ours:>12s}  {verdict}")
    return "\n".join(lines)
