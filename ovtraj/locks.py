"""Advisory file locks (``flock``) for processes sharing a run.

The kernel releases a ``flock`` lock when its process ends, however it ends, so
a killed writer never leaves a stale lock: the next process simply acquires it
(stale-lock recovery needs no timeout or process-id guessing). A lock file holds
its last holder's host and process id, for messages only.
"""

from __future__ import annotations

import fcntl
import os
import socket
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from ovtraj.files import StoreError, os_error_text

__all__ = ["held", "hold", "hold_directory"]

_POLL_S = 0.05


def _open(path: Path) -> int:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        return os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as err:
        raise StoreError(f"cannot write {path}: {os_error_text(err)}") from None


def _holder(path: Path) -> str:
    try:
        text = path.read_text(encoding="utf-8").strip()
    except OSError:
        text = ""
    return text or "another process"


def _acquire(fd: int, mode: int, wait_s: float) -> bool:
    """Try ``flock`` until it succeeds or ``wait_s`` has passed (0: once)."""
    deadline = time.monotonic() + wait_s
    while True:
        try:
            fcntl.flock(fd, mode | fcntl.LOCK_NB)
            return True
        except BlockingIOError:
            if time.monotonic() >= deadline:
                return False
            time.sleep(_POLL_S)


@contextmanager
def hold(path: Path, *, shared: bool = False, wait_s: float = 0.0) -> Iterator[bool]:
    """Hold the lock at ``path`` for the ``with`` block; yields whether it was acquired.

    ``wait_s`` = 0 tries once; a positive wait retries until then and raises
    :class:`StoreError` naming the holder when the lock is still taken. An
    exclusive holder records its host and process id in the file.
    """
    fd = _open(path)
    acquired = False
    try:
        acquired = _acquire(fd, fcntl.LOCK_SH if shared else fcntl.LOCK_EX, wait_s)
        if not acquired and wait_s > 0:
            raise StoreError(f"{path}: still held by {_holder(path)} after {wait_s:g} s")
        if acquired and not shared:
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"{socket.gethostname()} pid {os.getpid()}\n".encode(), 0)
        yield acquired
    finally:
        if acquired:
            fcntl.flock(fd, fcntl.LOCK_UN)
        os.close(fd)


@contextmanager
def hold_directory(directory: Path, *, wait_s: float) -> Iterator[None]:
    """Hold an exclusive lock on ``directory`` itself (created if needed; no lock file).

    Raises :class:`StoreError` naming the directory when another process still
    holds it after ``wait_s``.
    """
    try:
        directory.mkdir(parents=True, exist_ok=True)
        fd = os.open(directory, os.O_RDONLY)
    except OSError as err:
        raise StoreError(f"cannot write {directory}: {os_error_text(err)}") from None
    try:
        if not _acquire(fd, fcntl.LOCK_EX, wait_s):
            raise StoreError(f"{directory}: another process is still writing it after {wait_s:g} s")
        yield
    finally:
        os.close(fd)  # releases the lock


def held(path: Path) -> bool:
    """Whether some process holds the lock at ``path`` (shared or exclusive); read-only."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except FileNotFoundError:
        return False
    except OSError as err:
        raise StoreError(f"{path}: unreadable ({os_error_text(err)})") from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    else:
        fcntl.flock(fd, fcntl.LOCK_UN)
        return False
    finally:
        os.close(fd)
