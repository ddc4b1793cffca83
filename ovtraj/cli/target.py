"""The ``target`` command: a TLE or OMM's mean elements as the project uses them (its
SGP4 ephemeris fitted)."""

from __future__ import annotations

import warnings
from typing import Annotated

import typer

from ovtraj.cli.common import JsonOpt, app, keyed_rows, print_json, print_rows
from ovtraj.config import ConfigError
from ovtraj.store.records import plain


@app.command()
def target(
    source: Annotated[
        str, typer.Argument(help="TLE or OMM file, http(s) URL, or scenario YAML with a source")
    ],
    epoch: Annotated[
        str | None,
        typer.Option("--epoch", help="fit epoch, ISO 8601 UTC (default: the scenario's, or now)"),
    ] = None,
    span_h: Annotated[
        float | None,
        typer.Option(
            "--span-h",
            help="fit span [h] (default: the scenario's target.source_settings.fit_span_h, "
            "else configs/target_sources.yaml's, 24 h)",
            show_default=False,
        ),
    ] = None,
    catalog_number: Annotated[
        int | None,
        typer.Option(
            "--catalog-number",
            help="pick one set of several (default: the only one)",
            show_default=False,
        ),
    ] = None,
    as_json: JsonOpt = False,
) -> None:
    """The project's mean elements of a TLE / OMM, fitted to its SGP4 ephemeris.

    Example: `ovtraj target configs/targets/iss-like-2026-12-01.tle --span-h 24`"""
    from ovtraj.target_sources import fit_source

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            fit = fit_source(source, epoch_utc=epoch, span_h=span_h, catalog_number=catalog_number)
        except ConfigError as err:
            typer.echo(str(err), err=True)
            raise typer.Exit(code=2) from None
    for warning in caught:
        typer.echo(f"warning: {warning.message}", err=True)
    row = plain(fit.to_row())
    if as_json:
        print_json(row)
    else:
        print_rows(f"target: {fit.source.label()}", keyed_rows(row, digits=6))
    if not fit.converged:
        raise typer.Exit(code=1)
