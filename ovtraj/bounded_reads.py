"""Reading what the user gives, bounded: a text file of at most a size, YAML without
anchors or aliases.

Every config, scenario, launcher and plan file goes through :func:`read_text_file` (a
regular file only, never waiting on a FIFO or reading ``/dev/zero`` without end, within a
size cap) and :func:`read_yaml` (no shared nodes, so a small file cannot expand into
billions of values). This module sits below the configuration and the store, which both
use it.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path
from typing import IO, Any

import yaml

from ovtraj.errors import ConfigError

# libyaml's parser when the wheel has it: the scenario file parses ~10x faster.
_YAML_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def read_yaml(source: str | IO[str]) -> Any:
    """``yaml.safe_load`` with the C parser when available (same results, same errors),
    refusing anchors and aliases (``&name``, ``*name``).

    An alias shares a node, so ten levels of ten aliases in a 30 kB file ("billion
    laughs") make 10^10 leaves to validate, to walk and to echo in an error (measured at
    10^7: 8 s and a 52 MB error line). No shipped file uses them. The parser's events
    are checked first (no value is built), then the text is loaded;
    :class:`yaml.composer.ComposerError` names the line of the first anchor or alias.
    """
    text = source if isinstance(source, str) else source.read()
    # an anchor needs a "&", an alias a "*": a text with neither is read in one pass
    # (the events pass costs as much as the load: 3.6 ms more on the scenario's 3 ms)
    events = yaml.parse(text, Loader=_YAML_LOADER) if "&" in text or "*" in text else ()
    for event in events:
        if isinstance(event, yaml.AliasEvent) or getattr(event, "anchor", None) is not None:
            raise yaml.composer.ComposerError(
                None,
                None,
                "YAML anchors and aliases (&name, *name) are not accepted; write the values out",
                event.start_mark,
            )
    return yaml.load(text, Loader=_YAML_LOADER)


_FILE_KINDS = (
    (stat.S_ISDIR, "a directory"),
    (stat.S_ISFIFO, "a FIFO"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


def file_kind(mode: int) -> str:
    """What a file of ``st_mode`` ``mode`` that is not a regular file is, for an error
    line: ``a FIFO``, ``a character device`` (``/dev/zero``), ``a directory``..."""
    return next((name for test, name in _FILE_KINDS if test(mode)), "a special file")


def read_text_file(path: str | Path, *, max_bytes: int | None, limit: str = "") -> str:
    """The UTF-8 text of the regular file ``path`` of at most ``max_bytes`` bytes [B]
    (None: its size alone bounds the read); a :class:`~ovtraj.errors.ConfigError`
    naming the file for anything else.

    The file is opened without blocking (a FIFO would wait for a writer forever) and
    checked before a byte is read: a FIFO, a device (``/dev/zero`` never ends), a
    directory or a socket is refused, and so is a file larger than ``max_bytes``, also
    one that grows while it is read. ``limit`` names the setting behind ``max_bytes``
    in the error (``config_file_max_kib = 1024 KiB``).
    """
    where = str(path)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0)
    try:
        fd = os.open(path, flags)
    except OSError as err:
        raise ConfigError([f"cannot read the file: {err.strerror}"], where) from None
    info = os.fstat(fd)
    if not stat.S_ISREG(info.st_mode):
        os.close(fd)
        raise ConfigError([f"not a regular file ({file_kind(info.st_mode)})"], where)
    with os.fdopen(fd, "rb") as handle:
        too_big = f"larger than {limit or f'{max_bytes} B'}"
        if max_bytes is not None and info.st_size > max_bytes:
            raise ConfigError([f"{info.st_size} B: {too_big}"], where)
        try:
            data = handle.read() if max_bytes is None else handle.read(max_bytes + 1)
        except OSError as err:
            raise ConfigError([f"cannot read the file: {err.strerror}"], where) from None
    if max_bytes is not None and len(data) > max_bytes:  # it grew while being read
        raise ConfigError([f"grew while read: {too_big}"], where)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as err:
        raise ConfigError([f"not a UTF-8 text file: {err}"], where) from None
