"""``ovtraj ARGS`` in this process, answered as ``subprocess.run`` answers.

:func:`run_cli` runs a command line through :func:`ovtraj.cli.run_command` (the body of
the entry point: the same exit code for every fault) and returns a
``subprocess.CompletedProcess`` with its exit code and the text it wrote on stdout and
stderr. It saves the ~1-2 s a new process spends importing numpy, numba and heyoka and
loading their kernels, where nothing about a separate process is being tested;
tests/test_cli.py runs a few commands both ways and compares the three.

What a separate process would give each command and this one must set and restore:

* ``sys.stdout``/``sys.stderr``: replaced for the run (``typer.echo``, ``print`` and the
  rich consoles of :mod:`ovtraj.cli` look them up when they write);
* the ``ovtraj`` loggers' handler and level and the ``--quiet`` setting, which
  :func:`ovtraj.cli.progress.configure_logging` sets for each command: restored after;
* ``env``: entries set (or, given None, removed) for the run and restored after.
  Another ``OVTRAJ_CONFIG_DIR`` is refused: the configuration files are read once per
  process (``lru_cache``), so another folder needs a process of its own;
* ``cwd``: changed for the run and back after;
* :func:`ovtraj.version.code_version`, cached once per process: computed again (~30 ms)
  before each command, so that the command names the checkout as it is when it starts, as
  a new process does (a run id holds it: a run compared with another process's run);
* ``timeout``: an alarm ends a command that does not return (``subprocess.TimeoutExpired``,
  as ``subprocess.run`` raises), so that a hang fails the test, not the suite.

A command that is killed or interrupted, that races another process on one store, or
whose process itself is the point (a fresh install, the entry point's last line) still
runs as a real process.
"""

from __future__ import annotations

import contextlib
import io
import logging
import os
import signal
import subprocess
from collections.abc import Iterator, Mapping
from pathlib import Path

from ovtraj.cli import progress, run_command
from ovtraj.version import code_version

__all__ = ["run_cli"]

PROGRAM = "ovtraj"  # the name in usage lines, as the installed command's
REFUSED_ENV = ("OVTRAJ_CONFIG_DIR",)  # read once per process: needs a process of its own


class _Hung(BaseException):
    """Raised by the alarm (a BaseException: the CLI turns every Exception into a line)."""


def _hung(signum, frame) -> None:
    raise _Hung


@contextlib.contextmanager
def _environment(env: Mapping[str, str | None] | None) -> Iterator[None]:
    changes = dict(env or {})
    refused = [n for n in REFUSED_ENV if n in changes and changes[n] != os.environ.get(n)]
    if refused:
        raise ValueError(f"{refused}: read once per process; run this command in a subprocess")
    saved = {name: os.environ.get(name) for name in changes}
    try:
        for name, value in changes.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = str(value)
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


@contextlib.contextmanager
def _logging_kept() -> Iterator[None]:
    logger = logging.getLogger("ovtraj")
    handlers, level, settings = list(logger.handlers), logger.level, dict(progress._SETTINGS)
    try:
        yield
    finally:
        logger.handlers[:] = handlers
        logger.setLevel(level)
        progress._SETTINGS.update(settings)


@contextlib.contextmanager
def _alarm(timeout: float | None, args: list[str]) -> Iterator[None]:
    if timeout is None:
        yield
        return
    previous = signal.signal(signal.SIGALRM, _hung)
    signal.setitimer(signal.ITIMER_REAL, timeout)
    try:
        yield
    except _Hung:
        raise subprocess.TimeoutExpired(args, timeout) from None
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def run_cli(
    *args: str | os.PathLike,
    env: Mapping[str, str | None] | None = None,
    cwd: str | os.PathLike | None = None,
    timeout: float | None = 600,
) -> subprocess.CompletedProcess:
    """``ovtraj ARGS`` in this process: ``returncode``, ``stdout`` and ``stderr`` (text) as
    ``subprocess.run([ovtraj, *args], capture_output=True, text=True, env=os.environ | env,
    cwd=cwd, timeout=timeout)`` gives them; ``env`` values None remove a variable."""
    argv = [os.fspath(a) for a in args]
    out, err = io.StringIO(), io.StringIO()
    here = Path.cwd()
    with _environment(env), _logging_kept():
        if cwd is not None:
            os.chdir(cwd)
        try:
            with (
                _alarm(timeout, [PROGRAM, *argv]),
                contextlib.redirect_stdout(out),
                contextlib.redirect_stderr(err),
            ):
                code_version.cache_clear()
                code = run_command(argv, prog_name=PROGRAM)
        finally:
            os.chdir(here)
    return subprocess.CompletedProcess([PROGRAM, *argv], code, out.getvalue(), err.getvalue())
