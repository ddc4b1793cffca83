"""Which point of a verified front a mission plan flies (the options ``--pick``,
``--weights``, ``--max-time-h``, ``--max-dv-mps``, ``--min-payload-kg`` of ``pipeline``
and ``plan``; ``window`` takes all but ``--pick``), and the written plan's paths as the
two commands print them."""

from __future__ import annotations

from typing import Annotated, Any

import typer

from ovtraj.cli.common import print_json, renamed_options

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


# How a refused pick names its input: by the option, as the command was given it.
PICK_OPTIONS = {
    "pick": "--pick",
    "weights": "--weights",
    "max_time_h": "--max-time-h",
    "max_dv_mps": "--max-dv-mps",
    "min_payload_kg": "--min-payload-kg",
}


def pick_from_options(
    index: int | None,
    weights: str | None,
    max_time_h: float | None,
    max_dv: float | None,
    min_payload: float | None,
) -> Any:
    """The pick of the options, checked before any work as the flows check theirs
    (:func:`ovtraj.pipeline.pick.checked_pick`): one line naming the option, exit 2."""
    from ovtraj.pipeline.pick import checked_pick

    try:
        return checked_pick(index, weights, max_time_h, max_dv, min_payload, shown=PICK_OPTIONS)
    except ValueError as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None


def print_plan(planned: dict[str, Any], as_json: bool, extra: dict[str, Any]) -> None:
    """The written plan's paths (absolute) and why its point was picked."""
    paths = {
        "plan_json": str(planned["json"].resolve()),
        "plan_yaml": str(planned["yaml"].resolve()),
        "report": str(planned["report"].resolve()),
        "plots": [str(p.resolve()) for p in planned["plots"]],
    }
    if as_json:
        print_json(extra | {"pick": planned["pick"]} | paths)
        return
    typer.echo(f"picked {planned['pick']}")
    typer.echo(f"plan: {paths['plan_json']}")
    typer.echo(f"plan: {paths['plan_yaml']}")
    for path in paths["plots"]:
        typer.echo(f"plot: {path}")
    typer.echo(f"report: {paths['report']}")
