"""Where a run store is: the root named on the command line (``--store``), else the one a
config file names (relative to that file's folder), else the workspace's ``runs/``
(:func:`ovtraj.paths.workspace`). Either may be an object store (``s3://bucket/prefix``,
:mod:`ovtraj.store.backends`).

A root is resolved when it is named (a symbolic link chosen for it is followed there,
once); below it no write passes through a symbolic link
(:func:`ovtraj.store.files.make_folders`). Where results go never depends on the current
directory unless a relative path is given on the command line.
"""

from __future__ import annotations

from pathlib import Path

from ovtraj.paths import workspace
from ovtraj.store.backends import S3Path, location


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
