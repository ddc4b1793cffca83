"""Where ovtraj reads its shipped files and where it writes the user's results.

Shipped files (read only): the configuration files (Earth model, atmosphere,
scenarios, launchers, published cases) and the small reference data (the default
scenario's launch fit). In a source checkout they are the repository's
``configs/`` and ``data/reference/``; an installed package carries the same files
as package data (``ovtraj/configs``, ``ovtraj/reference``; see ``setup.py``).
``OVTRAJ_CONFIG_DIR`` points the configuration files elsewhere.

The workspace (written): ``OVTRAJ_HOME`` if set, else ``<repository>/data`` in a
source checkout, else ``$XDG_DATA_HOME/ovtraj`` (``~/.local/share/ovtraj``). It
holds the run store (``runs/``), solved launch fits (``launch_fit/``) and other
command outputs. The workspace and a store's root are resolved when they are named (a
symbolic link chosen for them is followed there, once); below them no write passes through
a symbolic link (:func:`ovtraj.store.files.make_folders`). Nothing is ever written inside
the installed package, and where
results go never depends on the current directory: a relative path in a config
file is relative to that file's folder.
"""

from __future__ import annotations

import importlib.resources
import os
import stat
from pathlib import Path
from typing import IO, Any

import yaml

from ovtraj.store.backends import S3Path, location

# libyaml's parser when the wheel has it: the scenario file parses ~10x faster.
_YAML_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)

PACKAGE_DIR = Path(str(importlib.resources.files("ovtraj")))
REPO_ROOT = PACKAGE_DIR.parent


def source_checkout() -> bool:
    """Whether this ``ovtraj`` runs from a repository checkout (editable or not installed)."""
    return (REPO_ROOT / "pyproject.toml").is_file() and (REPO_ROOT / "configs").is_dir()


def config_dir() -> Path:
    """Directory holding the YAML configuration files."""
    if "OVTRAJ_CONFIG_DIR" in os.environ:
        return Path(os.environ["OVTRAJ_CONFIG_DIR"]).resolve()
    return REPO_ROOT / "configs" if source_checkout() else PACKAGE_DIR / "configs"


def config_path(name: str) -> Path:
    """Path of a file inside the configuration directory; raises if it is missing."""
    path = config_dir() / name
    if not path.is_file():
        raise FileNotFoundError(f"configuration file not found: {path}")
    return path


def scenario_file(config: str | Path | None) -> Path:
    """The scenario file of a command or flow: ``config``, else the shipped
    ``scenario.yaml`` (the same default for ``ovtraj`` and every flow, wherever it runs)."""
    return Path(config) if config is not None else config_path("scenario.yaml")


def reference_dir() -> Path:
    """Directory of the shipped reference data (read only)."""
    return REPO_ROOT / "data" / "reference" if source_checkout() else PACKAGE_DIR / "reference"


def workspace() -> Path:
    """The user's workspace (absolute): ``OVTRAJ_HOME``, see the module notes."""
    if os.environ.get("OVTRAJ_HOME"):
        return Path(os.environ["OVTRAJ_HOME"]).expanduser().resolve()
    if source_checkout():
        return (REPO_ROOT / "data").resolve()
    base = os.environ.get("XDG_DATA_HOME") or Path.home() / ".local" / "share"
    return Path(base).expanduser().resolve() / "ovtraj"


def resolve(path: str | Path | S3Path, base_dir: Path | None) -> Path | S3Path:
    """``path`` made absolute: relative to ``base_dir`` (a config file's folder) if given.

    An object-store URL (``s3://bucket/prefix``) is absolute already.
    """
    path = location(path)
    if isinstance(path, S3Path):
        return path
    path = path.expanduser()
    if not path.is_absolute():
        path = (base_dir or Path.cwd()) / path
    return path.resolve()


def store_root(
    configured: str | None, base_dir: Path | None, override: str | Path | S3Path | None
) -> Path | S3Path:
    """The run store's root: ``override`` (``--store``), else the configured one
    (relative to the config file's folder), else the workspace's ``runs/``. Either may
    be an object store (``s3://bucket/prefix``, :mod:`ovtraj.store.backends`)."""
    if override is not None:
        return resolve(override, None)
    if configured:
        return resolve(configured, base_dir)
    return workspace() / "runs"


def read_yaml(source: str | IO[str]) -> Any:
    """``yaml.safe_load`` with the C parser when available (same results, same errors),
    refusing anchors and aliases (``&name``, ``*name``).

    An alias shares a node, so ten levels of ten aliases in a 30 kB file ("billion
    laughs") make 10^10 leaves to validate, to walk and to echo in an error (issue 44:
    8 s and a 52 MB error line at 10^7). No shipped file uses them. The parser's events
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
    (None: its size alone bounds the read); a :class:`~ovtraj.config.base.ConfigError`
    naming the file for anything else.

    The file is opened without blocking (a FIFO would wait for a writer forever) and
    checked before a byte is read: a FIFO, a device (``/dev/zero`` never ends), a
    directory or a socket is refused, and so is a file larger than ``max_bytes``, also
    one that grows while it is read. ``limit`` names the setting behind ``max_bytes``
    in the error (``config_file_max_kib = 1024 KiB``).
    """
    from ovtraj.errors import ConfigError

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
