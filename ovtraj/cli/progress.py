"""Log output and progress bars of the ``ovtraj`` command, on stderr (stdout holds the
results only).

The library logs to the ``ovtraj.*`` loggers and never configures them; the command
does, once per invocation, with :func:`configure_logging` (``--quiet``: warnings and
errors only; ``--verbose``: debug messages too): one line per message, no traceback.

:func:`progress_bar` is a context manager yielding ``update(done, total, label)``: a
rich progress bar with the elapsed time and an ETA while stderr is a terminal; nothing
with ``--quiet``, when the command prints JSON (``enabled=False``) or when stderr is not
a terminal (a pipe or a file; each update is then a debug message, seen with
``--verbose``). Log messages printed while a bar is shown appear above it, and so do
lines of the command's output written with :func:`echo` (``typer.echo`` writes past the
bar: it writes the bytes of stdout).
"""

from __future__ import annotations

import contextlib
import logging
import sys
from collections.abc import Callable, Iterator

from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

__all__ = ["Update", "configure_logging", "console", "echo", "progress_bar", "quiet"]

Update = Callable[..., None]
"""``update(done, total=None, label=None)``: ``done`` of ``total`` (None: unknown) units
of work, ``label`` what is being done now."""

# stderr as it is when written to (a test runner may replace sys.stderr), shared by the
# log handler and the progress bars so that messages print above a bar.
console = Console(stderr=True, highlight=False, soft_wrap=True)

_LOGGER = logging.getLogger("ovtraj")
_SETTINGS = {"quiet": False}
_PREFIXES = {logging.DEBUG: "debug: ", logging.WARNING: "warning: ", logging.ERROR: "error: "}


class _LineHandler(logging.Handler):
    """One line per message on :data:`console`: ``warning: ...``, no traceback."""

    def emit(self, record: logging.LogRecord) -> None:
        try:
            text = " ".join(record.getMessage().split("\n"))
            prefix = _PREFIXES.get(record.levelno, "error: " if record.levelno > 30 else "")
            if record.levelno == logging.DEBUG:
                prefix += f"{record.name}: "
            console.print(prefix + text, markup=False, emoji=False, highlight=False)
        except Exception:  # a closed stream: nothing more can be said there
            self.handleError(record)


def configure_logging(*, quiet: bool = False, verbose: bool = False) -> None:
    """The ``ovtraj`` loggers to stderr: warnings and errors when ``quiet``, debug
    messages too when ``verbose``, else progress messages (info) too. Again replaces
    the previous configuration (one handler, whatever the number of invocations)."""
    for handler in [h for h in _LOGGER.handlers if isinstance(h, _LineHandler)]:
        _LOGGER.removeHandler(handler)
    _LOGGER.addHandler(_LineHandler())
    _LOGGER.setLevel(logging.WARNING if quiet else logging.DEBUG if verbose else logging.INFO)
    _SETTINGS["quiet"] = quiet


def echo(text: str) -> None:
    """A line of the command's output on stdout (flushed: a killed command leaves its lines),
    above the progress bar when one is shown on the same terminal: a ``progress=`` callback
    for the library's messages."""
    print(text, flush=True)


def quiet() -> bool:
    """Whether ``--quiet`` was given (no progress, warnings and errors only)."""
    return _SETTINGS["quiet"]


@contextlib.contextmanager
def progress_bar(description: str, *, enabled: bool = True) -> Iterator[Update]:
    """A progress bar on stderr while the block runs; yields ``update(done, total=None,
    label=None)``. Shown only when ``enabled`` (pass ``not as_json``), not ``--quiet``
    and stderr is a terminal; otherwise each update is a debug message."""
    if not enabled or quiet() or not console.is_terminal:
        log = logging.getLogger("ovtraj.progress")

        def log_update(done: int, total: int | None = None, label: str | None = None) -> None:
            of = f"/{total}" if total is not None else ""
            log.debug(f"{description}{f' ({label})' if label else ''}: {done}{of}")

        yield log_update
        return
    bar = Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("elapsed"),
        TimeElapsedColumn(),
        TextColumn("ETA"),
        TimeRemainingColumn(),
        console=console,
        transient=True,
        # Results printed on stdout while the bar is shown go above it when both are the
        # terminal; stdout sent elsewhere is left alone.
        redirect_stdout=bool(getattr(sys.stdout, "isatty", lambda: False)()),
        redirect_stderr=True,
    )
    with bar:
        task = bar.add_task(description, total=None)

        def update(done: int, total: int | None = None, label: str | None = None) -> None:
            shown = f"{description}: {label}" if label else description
            bar.update(task, completed=done, total=total, description=shown)

        yield update
