"""What ovtraj reads and writes at most, and how long it waits on an object store
(``configs/io_limits.yaml``).

* the size of a config, scenario, launcher, dispersions, export-settings or plan file
  (:func:`read_config_file`; element sets have ``url_max_mib`` of
  ``configs/target_sources.yaml``), read only if it is a regular file
  (:func:`ovtraj.bounded_reads.read_text_file`);
* the characters of a value or a name echoed in an error line (:func:`echoed`), and of
  a stored text (a name, a tag, an id) a command's plain output shows (:func:`shown_text`);
* the disk a DoE sample takes, for the estimate checked against the free disk before a
  DoE writes (:func:`ovtraj.runs.execute.check_free_disk`);
* the nesting depth and the number length of a JSON file read
  (:func:`ovtraj.store.files.json_data`);
* the runs ``ovtraj fly --monte-carlo`` flies without ``--allow-long-run``, and the
  seconds a run takes for the estimate it prints first;
* the waits of an object-store request, for its connection and for each read of its
  answer (:mod:`ovtraj.store.backends`).

Like ``configs/orchestration.yaml`` these belong to no scenario: they never change a
result or a run id.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

from ovtraj.bounded_reads import read_text_file
from ovtraj.config.base import ConfigError, StrictModel, bounded, model_from_dict, parse_yaml
from ovtraj.formatting import one_line
from ovtraj.paths import config_path
from ovtraj.units import BYTES_PER_GIB, BYTES_PER_KIB

FILE = "io_limits.yaml"


class IoLimits(StrictModel):
    """``configs/io_limits.yaml``."""

    config_file_max_kib: float = bounded(
        unit="KiB", gt=0, le=1024 * 1024, description="largest config, scenario or plan file read"
    )
    echo_max_chars: int = bounded(
        ge=16, le=1_000_000, description="a value echoed in an error line is cut to this"
    )
    shown_max_chars: int = bounded(
        unit="characters",
        ge=16,
        le=1_000_000,
        description="a stored text shown in a command's plain output is cut to this",
    )
    doe_bytes_per_sample: float = bounded(
        unit="B", gt=0, le=1e12, description="disk a DoE sample takes in the run store"
    )
    doe_estimate_shown_gib: float = bounded(
        unit="GiB", ge=0, le=1e6, description="a DoE estimated above this says its estimate"
    )
    json_max_depth: int = bounded(
        unit="levels", ge=8, le=900, description="deepest nesting of a JSON file read"
    )
    json_number_max_chars: int = bounded(
        unit="characters", ge=24, le=4300, description="longest number in a JSON file read"
    )
    fly_monte_carlo_max_runs: int = bounded(
        unit="runs",
        ge=1,
        le=100_000,
        description="`ovtraj fly --monte-carlo N` beyond this needs --allow-long-run",
    )
    fly_monte_carlo_j2_s_per_run: float = bounded(
        unit="s", gt=0, le=1e6, description="a dispersed flight under --fidelity j2 takes"
    )
    fly_monte_carlo_high_s_per_run: float = bounded(
        unit="s", gt=0, le=1e6, description="a dispersed flight under --fidelity high takes"
    )
    s3_connect_timeout_s: float = bounded(
        unit="s", gt=0, le=3600, description="an object-store request waits for its connection"
    )
    s3_read_timeout_s: float = bounded(
        unit="s", gt=0, le=3600, description="an object-store request waits for each read"
    )

    @property
    def config_file_max_bytes(self) -> int:
        """``config_file_max_kib`` in bytes [B]."""
        return int(self.config_file_max_kib * BYTES_PER_KIB)

    @property
    def doe_estimate_shown_bytes(self) -> float:
        """``doe_estimate_shown_gib`` in bytes [B]."""
        return self.doe_estimate_shown_gib * BYTES_PER_GIB


@lru_cache(maxsize=1)
def io_limits() -> IoLimits:
    """The shipped ``configs/io_limits.yaml`` (``OVTRAJ_CONFIG_DIR`` moves it)."""
    try:
        path = config_path(FILE)
    except FileNotFoundError as err:
        raise ConfigError([str(err)], FILE) from None
    # The file that caps every other file cannot be capped by itself: it is read only if
    # it is a regular file (its size bounds the read), and a value of it echoed in an
    # error can be no longer than the file.
    text = read_text_file(path, max_bytes=None)
    try:
        data = parse_yaml(text)
    except ValueError as err:
        raise ConfigError([str(err)], str(path)) from None
    return model_from_dict(IoLimits, data, str(path), echo_max_chars=max(len(text), 1))


def read_config_file(path: str | Path) -> str:
    """The text of a config, scenario or plan file: a regular UTF-8 file of at most
    ``config_file_max_kib``; :class:`ConfigError` naming the file otherwise."""
    limits = io_limits()
    return read_text_file(
        path,
        max_bytes=limits.config_file_max_bytes,
        limit=f"config_file_max_kib = {limits.config_file_max_kib:g} KiB ({FILE})",
    )


def echoed(text: str, max_chars: int | None = None) -> str:
    """``text`` as one printable line of at most ``max_chars`` characters (default:
    ``echo_max_chars``): every non-printable character escaped, a longer text cut in the
    middle (:func:`ovtraj.formatting.one_line`). For a value, echo ``repr(value)``."""
    limit = io_limits().echo_max_chars if max_chars is None else max_chars
    return one_line(text, limit)


def shown_text(value: object) -> str:
    """A stored text (a scenario or target name, a tag, an id or a status read from a
    file) as a command's plain output shows it: :func:`echoed` to ``shown_max_chars``, so
    it stays one line, sends no terminal control sequence and a 5 MB value prints as a
    few hundred characters (``--json`` gives it whole, escaped by JSON)."""
    return echoed(str(value), io_limits().shown_max_chars)
