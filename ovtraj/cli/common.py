"""What every ``ovtraj`` command shares: the typer app and its callback (``--version``,
``--quiet``, ``--verbose``), the options several command families take (the scenario,
``--json``, ``--target``, ``--store``), the old spellings of renamed options
(:func:`renamed_options`), loading the scenario and the run store, a refusal as one line
and an exit code (:func:`exits_on`), and printing a result (a table of labelled rows, a
rich table on :func:`table_console`, or one JSON object on one line)."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path
from typing import Annotated, Any, ClassVar

import typer
import typer.core
from rich.console import Console

from ovtraj.cli.progress import configure_logging
from ovtraj.config import ConfigError, Scenario
from ovtraj.config.io_limits import shown_text
from ovtraj.formatting import joined, quantity, split_unit
from ovtraj.paths import scenario_file
from ovtraj.store.paths import store_root
from ovtraj.store.records import json_text, plain
from ovtraj.version import code_version

app = typer.Typer(
    # `ovtraj --install-completion` adds tab completion of commands and options to the
    # user's shell (bash, zsh, fish, PowerShell).
    add_completion=True,
    no_args_is_help=True,
    help="Whole-mission trajectory planning of a small reusable orbital vehicle.",
    # Markdown, not rich markup: rich would take a unit such as `[m/s]` in a help text
    # for a style tag and drop it.
    rich_markup_mode="markdown",
)


def _flag_type(option: Any, ctx: Any) -> str | None:
    """The type column of an option's help: none for a flag (typer 0.29 shows `<bool>`)."""
    return None if getattr(option, "is_flag", False) else _OPTION_TYPE(option, ctx)


# typer's own hook for the column; left alone by a typer that no longer has it.
_OPTION_TYPE = getattr(typer.core.TyperOption, "display_type_rich", None)
if _OPTION_TYPE is not None:
    typer.core.TyperOption.display_type_rich = _flag_type


class _RenamedOptions(typer.core.TyperCommand):
    """A command that still takes its options' old spellings (:func:`renamed_options`)."""

    renames: ClassVar[dict[str, str]] = {}

    def parse_args(self, ctx: Any, args: list[str]) -> list[str]:
        # Shell completion parses resiliently, on every key press: no warning there.
        respelled = _respelled(args, self.renames, warn=not ctx.resilient_parsing)
        return super().parse_args(ctx, respelled)


def renamed_options(renames: dict[str, str]) -> type[typer.core.TyperCommand]:
    """The command class (``@app.command(cls=...)``) that takes each old spelling of
    ``renames`` (old -> new) as its new one, for one release, with one line on stderr:
    ``--max-dv is deprecated: use --max-dv-mps``. A new name without dashes (``CONFIG``)
    is an argument now: the old option's value is given as that argument. The old
    spellings are no options of the command, so its help and completion show the new
    ones only."""
    return type("RenamedOptions", (_RenamedOptions,), {"renames": dict(renames)})


def _respelled(args: list[str], renames: dict[str, str], warn: bool) -> list[str]:
    """``args`` with every old spelling of ``renames`` (``--old V``, ``--old=V``) in its new
    one; the value of an option that became an argument moved after the other words.
    Nothing after ``--`` is an option."""
    kept: list[str] = []
    moved: list[str] = []
    k = 0
    while k < len(args):
        word = args[k]
        if word == "--":
            kept += args[k:]
            break
        name, equals, value = word.partition("=")
        new = renames.get(name) if name.startswith("--") else None
        if new is None:
            kept.append(word)
        elif new.startswith("--"):
            _deprecated(name, f"use {new}", warn)
            kept.append(new + equals + value)
        elif equals or k + 1 < len(args):
            _deprecated(name, f"give it as the argument {new}", warn)
            if not equals:
                k += 1
                value = args[k]
            moved.append(value)
        else:  # no value: the parser names the option
            kept.append(word)
        k += 1
    return kept + moved


def _deprecated(old: str, instead: str, warn: bool) -> None:
    if warn:
        typer.echo(f"{old} is deprecated: {instead}", err=True)


ConfigArg = Annotated[
    Path | None,
    typer.Argument(
        help="scenario YAML file (default: the shipped scenario, `ovtraj paths`)",
        show_default=False,
    ),
]
JsonOpt = Annotated[
    bool,
    typer.Option(
        "--json",
        help="print one JSON object on stdout, nothing else (progress and logs on stderr)",
    ),
]
AllowUnconvergedOpt = Annotated[
    bool,
    typer.Option(
        "--allow-unconverged",
        help="exit 0 when the verification loop did not converge (by default exit 1; the "
        "front, plan and report are stored and printed either way)",
    ),
]
TargetOpt = Annotated[
    str | None,
    typer.Option(
        "--target",
        help="TLE/OMM file or URL replacing the scenario's target (default: the scenario's)",
        show_default=False,
    ),
]


def _version(value: bool) -> None:
    """The code version every stored run records (``0.1.0+g<commit>``, or ``+s<source
    digest>`` for an installed package): what ``history`` and ``runs`` show."""
    if value:
        typer.echo(f"ovtraj {code_version()}")
        raise typer.Exit()


@app.callback()
def main(
    version: Annotated[
        bool, typer.Option("--version", callback=_version, is_eager=True, help="show the version")
    ] = False,
    quiet: Annotated[
        bool,
        typer.Option("--quiet", "-q", help="warnings and errors only on stderr, no progress bars"),
    ] = False,
    verbose: Annotated[
        bool, typer.Option("--verbose", "-v", help="debug messages on stderr too")
    ] = False,
) -> None:
    """ovtraj command line. Results go to stdout; progress bars (while stderr is a
    terminal), progress messages and warnings to stderr, one line each."""
    if quiet and verbose:
        typer.echo("--quiet and --verbose: choose one", err=True)
        raise typer.Exit(code=2)
    configure_logging(quiet=quiet, verbose=verbose)


def loaded_scenario(config: Path | None, target: str | None = None) -> Scenario:
    """The scenario (the shipped one when ``config`` is None), its target replaced by the
    TLE/OMM file or URL ``target`` when given."""
    # Here, not at the top: the target sources load the SGP4 fit (scipy, heyoka, numba,
    # ~1 s) that `ovtraj --help` and the store's commands never need.
    from ovtraj.target_sources import load_scenario, load_scenario_with_target

    try:
        path = scenario_file(config)
        return load_scenario(path) if target is None else load_scenario_with_target(path, target)
    except ConfigError as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=2) from None


def print_rows(title: str, rows: list[tuple[str, Any]]) -> None:
    """A title and aligned ``label  value`` lines (a value not yet text through
    :func:`ovtraj.formatting.quantity`: ``-`` for None, 4 significant digits). The title
    and the values may hold text from a file (a scenario's name): escaped and cut
    (:func:`ovtraj.config.io_limits.shown_text`)."""

    typer.echo(shown_text(title))
    width = max(len(k) for k, _ in rows)
    for key, value in rows:
        shown = value if isinstance(value, str) else quantity(value)
        typer.echo(f"  {key:<{width}}  {shown_text(shown)}")


# A table row of a result: (label, key of the row or function of the row, unit[, digits]);
# the unit "s" shows a duration, "utc" an epoch (ovtraj.formatting.quantity).
RowSpec = list[tuple[Any, ...]]


def spec_rows(row: dict[str, Any], spec: RowSpec) -> list[tuple[str, str]]:
    """``(label, text)`` of every row of ``spec`` the result has a value for."""
    shown = []
    for label, how, unit, *digits in spec:
        value = how(row) if callable(how) else row.get(how)
        if value is not None and value != "":
            shown.append((label, quantity(value, unit, *digits)))
    return shown


def keyed_rows(row: dict[str, Any], digits: int = 4) -> list[tuple[str, str]]:
    """Every field of a flat row, labelled by its key without the unit suffix and shown
    in that unit with ``digits`` significant digits (``min_t_total_s`` -> ``min t total
    142.003 h``)."""
    shown = []
    for key, value in row.items():
        name, unit = split_unit(key)
        shown.append((name.replace("_", " "), quantity(value, unit, digits)))
    return shown


def joined_fields(
    row: dict[str, Any],
    pattern: str,
    names: tuple[str, ...],
    unit: str,
    decimals: int = 3,
    sep: str = " / ",
) -> str | None:
    """``a / b / c unit`` of ``row[pattern.format(name)]`` with ``decimals`` each; None
    when the stage did not get there."""
    values = [row.get(pattern.format(name)) for name in names]
    if any(v is None for v in values):
        return None
    return joined(values, unit, sep=sep, decimals=decimals)


def table_console() -> Console:
    """Where a command's tables go, stdout: no rich markup (a stored name holding ``[bold]``
    or ``[/]`` is text, not a style or a markup error; every stored text in a table goes
    through :func:`ovtraj.config.io_limits.shown_text`, escaped and cut), and every row
    whole when stdout is not a terminal (a pipe or a file)."""
    console = Console(highlight=False, markup=False)
    return console if console.is_terminal else Console(highlight=False, markup=False, width=10_000)


def print_json(value: Any) -> None:
    """One JSON object, on one line of stdout."""
    typer.echo(json_text(value, indent=None))


@contextlib.contextmanager
def exits_on(*kinds: type[BaseException], code: int = 2) -> Iterator[None]:
    """Run the block; an error of ``kinds`` is its message as one line on stderr and exit
    ``code`` (2: bad input or a fault; 1: an unmet result). An exit already decided
    (``typer.Exit``, a ``RuntimeError`` as some of ``kinds`` are) passes through."""
    try:
        yield
    except typer.Exit:
        raise
    except kinds as err:
        typer.echo(str(err), err=True)
        raise typer.Exit(code=code) from None


def report_stage(title: str, result: Any, rows: RowSpec, as_json: bool) -> None:
    """Print a stage result (JSON or a table: feasible, the reason if any, ``rows``);
    exit 1 when it is infeasible."""
    row = plain(result.to_row())
    if as_json:
        print_json(row)
    else:
        shown: list[tuple[str, Any]] = [("feasible", row["feasible"])]
        if row.get("reason"):
            shown.append(("reason", row["reason"]))
        print_rows(title, shown + spec_rows(row, rows))
    if not result.feasible:
        raise typer.Exit(code=1)


def run_store(
    root: str | None, scenario: Scenario | None = None, config: Path | None = None
) -> Any:
    """``--store``, else the scenario's store (relative to its file ``config``), else the
    workspace's (ovtraj.store.paths.store_root)."""
    from ovtraj.runs import RunStore

    if scenario is not None:
        return RunStore.for_scenario(scenario, config, root)
    return RunStore(root)


def store_location(root: str | None) -> Any:
    """``--store``, else the workspace's run store: its root folder or S3 prefix, without
    loading the run store's code (the catalog's commands read the layout only)."""

    return store_root(None, None, root)


StoreOpt = Annotated[
    str | None,
    typer.Option(
        "--store",
        help="run store root, a folder or s3://bucket/prefix (default: the scenario's "
        "mission.doe.store for a command given a scenario, else runs in the workspace, "
        "`ovtraj paths`)",
        show_default=False,
    ),
]


def option_limits(model: Any, name: str) -> dict[str, Any]:
    """A config field's bounds as typer's ``min``/``max``: the command refuses what the
    config would (one definition of each range, in ``ovtraj.config``)."""
    limits: dict[str, Any] = {}
    for constraint in model.model_fields[name].metadata:
        if getattr(constraint, "ge", None) is not None:
            limits["min"] = constraint.ge
        if getattr(constraint, "le", None) is not None:
            limits["max"] = constraint.le
    return limits
