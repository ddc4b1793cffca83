"""Locks of the processes sharing a run: ``flock`` on a local disk, leases on an object store.

Local: the kernel releases a ``flock`` lock when its process ends, however it ends,
so a killed writer never leaves a stale lock: the next process simply acquires it
(stale-lock recovery needs no timeout or process-id guessing). A lock file holds its
last holder's host and process id, for messages only.

Object store (:class:`ovtraj.store.backends.S3Path`): a lock is a lease object naming its
holder and its expiry. It is created only if absent (``If-None-Match``), renewed
by its holder every third of its lease while held, and taken over when it expired
(``If-Match`` on the stale lease, so one process wins), then deleted on release. A
killed holder's lease is stale after the lease (``locks.lease_s`` of
``configs/orchestration.yaml``, as the store's settings give it). A shared lock is one
lease per holder under the lock's key.
"""

from __future__ import annotations

import errno
import fcntl
import json
import os
import secrets
import socket
import stat
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from ovtraj.store.backends import PreconditionFailed, S3Path, StorageError, location
from ovtraj.store.files import StoreError, json_data, make_folders, os_error_text, read_bytes
from ovtraj.store.settings import given_settings

__all__ = ["held", "hold", "hold_directory"]


def _poll_s() -> float:
    """How long a waiter sleeps before it tries a held lock again [s]."""
    return given_settings().lock_poll_s


def _lease_s() -> float:
    """How long an object-store lease not renewed stays valid [s]; its holder renews it
    every third of it, so a slow request or a clock offset of tens of seconds is tolerated."""
    return given_settings().lock_lease_s


# A lock file is a regular file of the store: never opened through a symbolic link (a
# holder writes its name into it: a link would have it truncate a file elsewhere) and
# never waiting on a FIFO.
_NO_FOLLOW = getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0) | os.O_CLOEXEC


def _regular(fd: int, path: Path) -> int:
    """``fd`` if it is a regular file's; else closed, and StoreError naming ``path``."""
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        raise StoreError(f"{path}: not a regular file, so not a lock; left alone")
    return fd


def _open(path: Path) -> int:
    try:
        make_folders(path.parent)  # no symbolic link on the path (a lock is a stored file)
        fd = os.open(path, os.O_RDWR | os.O_CREAT | _NO_FOLLOW, 0o666)  # less the umask
    except OSError as err:
        if err.errno == errno.ELOOP:
            raise StoreError(f"{path}: a symbolic link, so not a lock; left alone") from None
        raise StoreError(f"cannot write {path}: {os_error_text(err)}") from None
    return _regular(fd, path)


def _holder(path: Path) -> str:
    try:  # read as a stored file: a FIFO or a link put there since is not waited on
        text = read_bytes(path).decode("utf-8", errors="replace").strip()
    except StoreError:
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
            time.sleep(_poll_s())


@contextmanager
def hold(path: Path, *, shared: bool = False, wait_s: float = 0.0) -> Iterator[bool]:
    """Hold the lock at ``path`` for the ``with`` block; yields whether it was acquired.

    ``wait_s`` = 0 tries once; a positive wait retries until then and raises
    :class:`StoreError` naming the holder when the lock is still taken. An
    exclusive holder records its host and process id in the file.
    """
    path = location(path)
    if isinstance(path, S3Path):
        with _lease(path, shared=shared, wait_s=wait_s) as acquired:
            yield acquired
        return
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
    directory = location(directory)
    if isinstance(directory, S3Path):
        with _lease(directory / ".lock", shared=False, wait_s=wait_s) as acquired:
            if not acquired:
                raise StoreError(f"{directory}: another process is still writing it")
            yield
        return
    try:
        make_folders(directory)
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
    """Whether some process holds the lock at ``path`` (shared or exclusive); read-only.
    ``path`` is a lock file or a directory locked itself (:func:`hold_directory`); one
    that is a symbolic link, a FIFO or a device counts as held: whatever asks (``ovtraj
    prune``, a run's status) then leaves it alone."""
    path = location(path)
    if isinstance(path, S3Path):
        try:
            return _lease_alive(path) or any(_lease_alive(p) for p in path.rglob("*"))
        except StorageError as err:
            raise StoreError(f"{path}: unreadable ({err})") from None
    try:
        fd = os.open(path, os.O_RDONLY | _NO_FOLLOW)
    except FileNotFoundError:
        return False
    except OSError as err:
        if err.errno == errno.ELOOP:
            return True
        raise StoreError(f"{path}: unreadable ({os_error_text(err)})") from None
    mode = os.fstat(fd).st_mode
    if not (stat.S_ISREG(mode) or stat.S_ISDIR(mode)):
        os.close(fd)
        return True
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    else:
        fcntl.flock(fd, fcntl.LOCK_UN)
        return False
    finally:
        os.close(fd)


# -- leases on an object store ----------------------------------------------------------------


def _lease_body(owner: str) -> bytes:
    return json.dumps({"owner": owner, "expires_unix_s": time.time() + _lease_s()}).encode()


def _lease_state(path: S3Path) -> tuple[dict | None, str | None]:
    """The lease at ``path`` and its ETag; (None, None) when there is none."""
    try:
        payload, etag = path.read_with_etag()
    except FileNotFoundError:
        return None, None
    try:
        content = json_data(payload)
    except ValueError:  # also nested too deep: not a lease
        content = {}
    return (content if isinstance(content, dict) else {}), etag


def _lease_alive(path: S3Path) -> bool:
    content, _ = _lease_state(path)
    return content is not None and float(content.get("expires_unix_s", 0.0)) > time.time()


def _take(path: S3Path, owner: str) -> str | None:
    """Create or take over (when stale) the lease at ``path``; its ETag, or None if held."""
    try:
        return path.put(_lease_body(owner), if_absent=True)
    except PreconditionFailed:
        pass
    content, etag = _lease_state(path)
    if content is None:
        return None  # released meanwhile: the next attempt creates it
    if float(content.get("expires_unix_s", 0.0)) > time.time():
        return None
    try:
        return path.put(_lease_body(owner), if_match=etag)
    except PreconditionFailed:
        return None  # another process took the stale lease first


@contextmanager
def _lease(path: S3Path, *, shared: bool, wait_s: float) -> Iterator[bool]:
    owner = f"{socket.gethostname()} pid {os.getpid()} {secrets.token_hex(4)}"
    key = path / owner.replace(" ", "-") if shared else path
    deadline = time.monotonic() + wait_s
    etag: str | None = None
    try:
        while True:
            if shared:
                etag = key.put(_lease_body(owner), if_absent=True)
            elif not any(_lease_alive(p) for p in path.rglob("*")):
                etag = _take(key, owner)  # exclusive: no live shared holder either
            if etag is not None or time.monotonic() >= deadline:
                break
            time.sleep(_poll_s() * 10)  # each attempt is a few requests
    except StorageError as err:
        raise StoreError(f"cannot write {key}: {err}") from None
    if etag is None:
        if wait_s > 0:
            content, _ = _lease_state(key)
            holder = (content or {}).get("owner", "another process")
            raise StoreError(f"{path}: still held by {holder} after {wait_s:g} s")
        yield False
        return
    renewer = _Renewer(key, owner, etag)
    renewer.start()
    try:
        yield True
    finally:
        renewer.stop()
        content, _ = _lease_state(key)
        if content is not None and content.get("owner") == owner:
            try:
                key.unlink(missing_ok=True)
            except (StorageError, FileNotFoundError):
                pass  # it expires by itself


class _Renewer(threading.Thread):
    """Renews a held lease every third of the lease until stopped (a daemon: dies with the
    process)."""

    def __init__(self, key: S3Path, owner: str, etag: str) -> None:
        super().__init__(daemon=True, name=f"lease {key}")
        self.key, self.owner, self.etag = key, owner, etag
        self.every_s = _lease_s() / 3.0
        self._stopped = threading.Event()

    def run(self) -> None:
        while not self._stopped.wait(self.every_s):
            try:
                self.etag = self.key.put(_lease_body(self.owner), if_match=self.etag)
            except (PreconditionFailed, StorageError):
                return  # lost (stalled for longer than the lease): writes stay create-only

    def stop(self) -> None:
        self._stopped.set()
        self.join(timeout=self.every_s)
