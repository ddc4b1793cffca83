"""Which point of a verified front a mission plan flies (the options ``--pick``,
``--weights``, ``--max-time-h``, ``--max-dv-mps``, ``--min-payload-kg`` of ``pipeline``
and ``plan``; ``window`` takes all but ``--pick``), and the written plan's paths as the
two commands print them."""

from __future__ import annotations

import math
from typing import Annotated, Any

import typer

from ovtraj.cli.common import _print_json, renamed_options
from ovtraj.config.io_limits import echoed

PickIndexOpt = Annotated[
    int | None,
    typer.Option(
        "--pick",
        min=0,
        help="front index, as `ovtraj front RUN` lists them (default: the best by --weights)",
        show_default=False,
    ),
]
WeightsOpt = Annotated[
    str | None,
    typer.Option(
        "--weights",
        help="T,dV,M weights on the normalised objectives, e.g. 1,1,2 (default: 1,1,1)",
        show_default=False,
    ),
]
MaxTimeOpt = Annotated[
    float | None,
    typer.Option(
        "--max-time-h",
        min=0.0,
        help="pick among points with T_total <= this [h] (default: no limit)",
        show_default=False,
    ),
]
MaxDvOpt = Annotated[
    float | None,
    typer.Option(
        "--max-dv-mps",
        min=0.0,
        help="pick among points with dV_total <= this [m/s] (default: no limit)",
        show_default=False,
    ),
]
MinLoadOpt = Annotated[
    float | None,
    typer.Option(
        "--min-payload-kg",
        min=0.0,
        help="pick among points with M_load >= this [kg] (default: no limit)",
        show_default=False,
    ),
]

# The limits' spellings before their names said their units: still taken for one release.
PickCommand = renamed_options({"--max-dv": "--max-dv-mps", "--min-payload": "--min-payload-kg"})


def _pick(
    index: int | None,
    weights: str | None,
    max_time_h: float | None,
    max_dv: float | None,
    min_payload: float | None,
    default_weights: tuple[float, float, float] | None = None,
) -> Any:
    """The pick of the options, checked before any work: one line naming the option, exit 2."""
    from ovtraj.pipeline import Pick
    from ovtraj.pipeline.pick import weights_problem

    parsed = default_weights
    if weights is not None:
        try:
            parsed = tuple(float(w) for w in weights.split(","))
            problem = weights_problem(parsed)
        except ValueError:
            problem = "must be three numbers separated by commas"
        if problem is not None:
            typer.echo(f"--weights {echoed(repr(weights))}: {problem}", err=True)
            raise typer.Exit(code=2) from None
    limits = {"--max-time-h": max_time_h, "--max-dv-mps": max_dv, "--min-payload-kg": min_payload}
    for option, value in limits.items():
        if value is not None and not math.isfinite(value):  # their min= lets inf (1e400) by
            typer.echo(f"{option} {value}: must be a finite number", err=True)
            raise typer.Exit(code=2)
    return Pick(index, parsed, max_time_h, max_dv, min_payload)


def _print_plan(planned: dict[str, Any], as_json: bool, extra: dict[str, Any]) -> None:
    """The written plan's paths (absolute) and why its point was picked."""
    paths = {
        "plan_json": str(planned["json"].resolve()),
        "plan_yaml": str(planned["yaml"].resolve()),
        "report": str(planned["report"].resolve()),
        "plots": [str(p.resolve()) for p in planned["plots"]],
    }
    if as_json:
        _print_json(extra | {"pick": planned["pick"]} | paths)
        return
    typer.echo(f"picked {planned['pick']}")
    typer.echo(f"plan: {paths['plan_json']}")
    typer.echo(f"plan: {paths['plan_yaml']}")
    for path in paths["plots"]:
        typer.echo(f"plot: {path}")
    typer.echo(f"report: {paths['report']}")
