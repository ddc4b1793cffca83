"""The ``ovtraj`` command line: the typer app (:mod:`ovtraj.cli.common`), its commands
(a module per family), and the entry point that turns every fault into one line and an
exit code.

The family modules import at module level only what ``ovtraj --help`` loads anyway
(pandas through the result records, the config models, a few small modules); a solver,
the run store or the pipeline loads inside the command that uses it. What two modules
share is a public name (``common.py``, or the family module it belongs to): no module
imports another's underscore name. tests/test_cli_imports.py checks both rules.
"""

from __future__ import annotations

import importlib
import os
import signal
import sys
from typing import Any

import typer

from ovtraj.cli.common import app
from ovtraj.config import ConfigError
from ovtraj.environment import BlasKernelError
from ovtraj.formatting import printable
from ovtraj.interrupts import interrupt_of
from ovtraj.store.files import StoreError

__all__ = ["app", "entry_point", "run_command"]

# Importing a family module registers its commands on the app: this order is the order
# of the commands in `ovtraj --help`.
_FAMILIES = (
    "stages",
    "studies",
    "workspace",
    "doe",
    "store",
    "pipeline",
    "window",
    "mission",
    "target",
    "tracking",
)
for _family in _FAMILIES:
    importlib.import_module(f"{__name__}.{_family}")


def _terminated(signum: int, frame: Any) -> None:
    # An exception, so that a run being written marks itself interrupted on the way out
    # (typer turns it into exit code 130).
    raise KeyboardInterrupt(f"signal {signum}")


def entry_point() -> None:
    """The ``ovtraj`` command: every fault is one line on stderr and exit 2, never a traceback.

    Exit codes: 0 done, 1 infeasible or unconverged result (or a failed check), 2 bad
    input or a fault (named; also a process on another OpenBLAS kernel than the pin,
    :mod:`ovtraj.environment`), 130 interrupted (SIGINT or SIGTERM; a run being written
    says ``interrupted`` in its manifest). ``OVTRAJ_DEBUG=1`` shows tracebacks.
    """
    signal.signal(signal.SIGTERM, _terminated)
    signal.signal(signal.SIGINT, _terminated)
    _exit(run_command())


def run_command(args: list[str] | None = None, prog_name: str | None = None) -> int:
    """Run the command line ``args`` (default: the process's) as :func:`entry_point`
    does, and return its exit code instead of ending the process (the tests call it).
    ``prog_name`` is the command's name in usage lines (default: click's, from the
    process's ``sys.argv[0]``; a test process passes ``"ovtraj"``)."""

    try:
        code = app(args=args, prog_name=prog_name, standalone_mode=False)
        if code == 130:
            typer.echo("interrupted", err=True)
    except typer.Exit as done:
        code = done.exit_code
    except typer.Abort:
        code = 130
        typer.echo("interrupted", err=True)
    except typer.exceptions.TyperException as err:  # usage errors: one line, exit 2
        _usage_error(err)
        code = int(getattr(err, "exit_code", 2))
    except KeyboardInterrupt:
        typer.echo("interrupted", err=True)
        code = 130
    except (StoreError, ConfigError, BlasKernelError) as err:
        typer.echo(str(err), err=True)
        code = 2
    except Exception as err:
        if interrupt_of(err) is not None:  # raised inside a compiled call (ovtraj.interrupts)
            typer.echo("interrupted", err=True)
            code = 130
        elif os.environ.get("OVTRAJ_DEBUG"):
            raise
        else:
            typer.echo(
                f"ovtraj: internal error: {type(err).__name__}: {printable(str(err))}", err=True
            )
            code = 2
    return code if isinstance(code, int) else 0


def _usage_error(err: Exception) -> None:
    """A usage error as one line naming the command and the option, e.g. ``ovtraj run:
    Invalid value for '--samples': ...``; no arguments at all still show the help."""
    show = getattr(err, "show", None)
    message = getattr(err, "format_message", None)
    if type(err).__name__ == "NoArgsIsHelpError" or message is None:
        show() if show else typer.echo(str(err), err=True)
        return
    ctx = getattr(err, "ctx", None)
    command = ctx.command_path if ctx is not None else "ovtraj"
    text = " ".join(str(message()).split())
    typer.echo(f"{command}: {text} (see `{command} --help`)", err=True)


def _exit(code: int) -> None:
    """End the process with ``code`` once its output is flushed, without the interpreter's
    teardown: Arrow's thread pools can abort the process there after a Parquet read
    (``terminate called without an active exception``, exit -6; apache/arrow#34314, once
    in our CI after `ovtraj verify` had printed its result). Nothing is left to run at
    exit: every file is written and closed, and the kernel releases the locks."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass  # a closed pipe: nothing more can be said there
    os._exit(code)
