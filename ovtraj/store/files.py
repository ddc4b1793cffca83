"""Stored files: atomic, never-overwriting writes and checked reads (the stores' primitives).

Writing: the content goes to a temporary file beside its target (a dot name that
ends in ``.tmp`` and carries the writer's host and process id), is flushed to disk
and then linked into place. A stored file is never replaced: writing a path that
exists with other content is refused (:class:`StoreError`), writing the same
content again is a no-op. Only mutable index files (a run's manifest) are
replaced, atomically (``replace=True``). Every write returns the file's
:class:`Digest` (size and SHA-256), which the stores' markers record.

Reading: :func:`read_bytes`, :func:`read_json` and :func:`read_parquet` verify a
file against its recorded digest (and a Parquet file against its declared schema)
before anything is parsed, and refuse a changed file naming it. A local read opens
regular files only, never through a final symbolic link and never waiting for a writer
(a FIFO, a device or a link to ``/dev/zero`` is refused at once, named), and checks the
size before reading: it must equal the recorded size, and no more is read; a file with
no recorded size (a manifest, a marker) may have at most ``reads.unrecorded_file_max_mib``
of ``configs/orchestration.yaml``. A recorded digest is a whole number of bytes up to
``reads.stored_file_max_mib`` and 64 hexadecimal digits (:meth:`Digest.from_json`); a
marker's file names stay inside its folder (:func:`marker_files`). Every read reads and
hashes the file; the Parquet decoding of a payload already decoded in this process is
reused (:class:`DecodedTables`, keyed by the SHA-256 just verified: the same digest is
the same bytes, so the same table).

No write follows a special file: every folder on the path of a written file must be a
real folder, not a symbolic link (:func:`make_folders`; the roots, a store's and the
workspace, are resolved when they are named, so a link chosen for a root is followed and
one put below it is refused), and a file already at the target is compared through the
regular-file reader above, never read when its size differs (:func:`holds`). A written
file gets the permissions the process's umask leaves of ``0o666`` (``open()``'s default),
as any file the user's tools create: ``umask 077`` keeps the store private.

Every operating-system failure (missing file, read-only file system, full disk)
becomes one :class:`StoreError` that names the file and the cause; an interrupted
write leaves at most a temporary file (:func:`remove_orphans` clears them).
"""

from __future__ import annotations

import errno
import functools
import hashlib
import json
import math
import os
import re
import secrets
import socket
import stat
import threading
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Any

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from ovtraj.bounded_reads import file_kind
from ovtraj.formatting import one_line
from ovtraj.store.backends import PreconditionFailed, S3Path, StorageError, location
from ovtraj.store.records import json_text
from ovtraj.store.settings import given_settings
from ovtraj.units import BYTES_PER_MIB

__all__ = [
    "DecodedTables",
    "Digest",
    "StoreError",
    "decoded_tables",
    "file_digest",
    "holds",
    "holds_other",
    "json_data",
    "make_folders",
    "marker_files",
    "os_error_text",
    "parquet_bytes",
    "read_bytes",
    "read_json",
    "read_parquet",
    "read_table",
    "remove_file",
    "remove_orphans",
    "writable_target",
    "write_bytes",
    "write_json",
    "write_parquet",
]

TEMPORARY_SUFFIX = ".tmp"
# Parquet encoding of every stored table (a format decision, like the schema version):
# zstd with byte-stream-split floats is 35-40 % smaller than snappy on trajectory tables.
PARQUET_COMPRESSION = "zstd"
PARQUET_COMPRESSION_LEVEL = 9
SHA256_HEX = re.compile(r"[0-9a-f]{64}")  # hashlib's hexdigest(): what a marker records
# A store holds regular files only: a final symbolic link is not followed (ELOOP) and a
# FIFO opens without waiting for a writer, so both are refused by the checks after opening.
_OPEN_STORED = (
    os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0) | os.O_CLOEXEC
)


class StoreError(RuntimeError):
    """A stored file that is missing, unreadable, changed or cannot be written (named)."""


@dataclass(frozen=True)
class Digest:
    """A file's size [bytes] and SHA-256 (hex), as recorded in a marker."""

    size: int
    sha256: str

    @classmethod
    def of(cls, payload: bytes) -> Digest:
        return cls(len(payload), hashlib.sha256(payload).hexdigest())

    def to_json(self) -> dict[str, Any]:
        return {"bytes": self.size, "sha256": self.sha256}

    @classmethod
    def from_json(cls, data: Any) -> Digest:
        """A marker's record of a file; ValueError saying what is wrong (the caller names
        the marker). The size must be a whole number of bytes within
        ``reads.stored_file_max_mib``: JSON's ``1e400`` is an infinite float, ``true`` a
        Python int, and neither is a size."""
        if not isinstance(data, dict):
            raise ValueError(f"not a file digest (a JSON {type(data).__name__}, not an object)")
        size, sha256 = data.get("bytes"), data.get("sha256")
        largest = int(given_settings().stored_file_max_mib * BYTES_PER_MIB)
        if type(size) is not int or not 0 <= size <= largest:
            found = "a whole number outside it" if type(size) is int else f"a {type(size).__name__}"
            raise ValueError(
                f'recorded "bytes" is not a whole number of bytes from 0 to {largest} '
                f"(reads.stored_file_max_mib of configs/orchestration.yaml); found {found}"
            )
        if not isinstance(sha256, str) or SHA256_HEX.fullmatch(sha256) is None:
            raise ValueError('recorded "sha256" is not 64 lowercase hexadecimal digits')
        return cls(size, sha256)


def os_error_text(err: OSError) -> str:
    """The cause of an operating-system error in a few words."""
    if err.errno == errno.ENOSPC:
        return "no space left on the device"
    if err.errno == errno.EROFS:
        return "read-only file system"
    if err.errno in (errno.EACCES, errno.EPERM):
        return "permission denied"
    return err.strerror or str(err)


def file_digest(path: Path) -> Digest:
    """Size [bytes] and SHA-256 of a stored file (a local one hashed as it is read, never
    held in memory whole)."""
    path = location(path)
    if isinstance(path, S3Path):
        return Digest.of(read_bytes(path))
    fd, _ = _open_stored(path)
    try:
        with open(fd, "rb", closefd=False) as handle:
            sha256 = hashlib.file_digest(handle, "sha256").hexdigest()
            size = handle.tell()
    except OSError as err:
        raise StoreError(f"{path}: unreadable ({os_error_text(err)})") from None
    finally:
        os.close(fd)
    return Digest(size, sha256)


def _open_stored(path: Path) -> tuple[int, os.stat_result]:
    """A descriptor of the regular file at the local ``path`` and its status; StoreError
    naming it for anything else (missing, a symbolic link, a FIFO, a device...)."""
    try:
        fd = os.open(path, _OPEN_STORED)
    except FileNotFoundError:
        raise StoreError(f"{path}: missing") from None
    except OSError as err:
        if err.errno == errno.ELOOP and os.path.islink(path):
            raise StoreError(f"{path}: a symbolic link, not a stored file; not read") from None
        raise StoreError(f"{path}: unreadable ({os_error_text(err)})") from None
    info = os.fstat(fd)
    if not stat.S_ISREG(info.st_mode):
        os.close(fd)
        raise StoreError(f"{path}: {file_kind(info.st_mode)}, not a stored file; not read")
    return fd, info


def _read_local(path: Path, expected: Digest | None) -> bytes:
    """The content of a local stored file, its size checked before anything is read: the
    recorded size exactly, else at most ``reads.unrecorded_file_max_mib``."""
    fd, info = _open_stored(path)
    try:
        if expected is not None and info.st_size != expected.size:
            raise StoreError(
                f"{path}: changed since it was stored ({info.st_size} bytes, "
                f"{expected.size} recorded)"
            )
        if expected is None:
            largest = int(given_settings().unrecorded_file_max_mib * BYTES_PER_MIB)
            if info.st_size > largest:
                raise StoreError(
                    f"{path}: {info.st_size} bytes, more than a file read without a recorded "
                    f"size may have ({largest}: reads.unrecorded_file_max_mib of "
                    "configs/orchestration.yaml); not read"
                )
        chunks, remaining = [], info.st_size
        with open(fd, "rb", buffering=0, closefd=False) as handle:
            while remaining > 0:  # a file that grows meanwhile is read up to the size checked
                chunk = handle.read(remaining)
                if not chunk:
                    break
                chunks.append(chunk)
                remaining -= len(chunk)
        return b"".join(chunks)
    except OSError as err:
        raise StoreError(f"{path}: unreadable ({os_error_text(err)})") from None
    finally:
        os.close(fd)


def marker_files(marker: Path, content: Any) -> dict[str, Digest]:
    """The files a marker (or manifest) ``content`` lists, by name relative to its folder,
    each checked: a name that stays inside the folder (no absolute path, ``..`` or control
    character) and a usable digest (:meth:`Digest.from_json`). StoreError naming the
    marker otherwise."""
    longest = given_settings().echo_max_chars
    listed = content.get("files") if isinstance(content, dict) else None
    if not isinstance(listed, dict):
        raise StoreError(f"{marker}: lists no file digests")
    digests = {}
    for name, record in listed.items():
        parts = PurePosixPath(name).parts
        if (
            not parts
            or parts[0] == "/"
            or any(part in (".", "..") for part in parts)
            or not name.isprintable()
            or "\\" in name
        ):
            shown = one_line(repr(name), longest)
            raise StoreError(
                f"{marker}: lists {shown}, a file name that leaves its folder "
                "or holds a control character (an absolute path, '..', a backslash); not read"
            )
        try:
            digests[name] = Digest.from_json(record)
        except ValueError as err:
            raise StoreError(f"{marker}: {one_line(name, longest)}: {err}") from None
    return digests


def _temporary_name(path: Path) -> Path:
    token = secrets.token_hex(4)
    return path.with_name(
        f".{path.name}.{socket.gethostname()}-{os.getpid()}-{token}{TEMPORARY_SUFFIX}"
    )


def write_bytes(path: Path, payload: bytes, *, replace: bool = False) -> Digest:
    """Store ``payload`` at ``path`` atomically; returns its digest.

    Without ``replace`` an existing file is never changed: the same content is
    accepted as already stored, other content is refused (:class:`StoreError`).
    """
    path = location(path)
    digest = Digest.of(payload)
    if isinstance(path, S3Path):
        return _put_object(path, payload, digest, replace)
    temporary = _temporary_name(path)
    try:
        make_folders(path.parent)
        with open(temporary, "xb") as handle:  # mode 0o666 less the umask
            handle.write(payload)
            handle.flush()
            os.fsync(handle.fileno())
        if replace:
            os.replace(temporary, path)
        else:
            _link_new(temporary, path, digest)
    except OSError as err:
        raise StoreError(f"cannot write {path}: {os_error_text(err)}") from None
    finally:
        try:
            os.unlink(temporary)
        except FileNotFoundError:
            pass
        except OSError:
            pass  # a read-only or vanished folder: nothing was left behind to remove
    return digest


def _put_object(path: S3Path, payload: bytes, digest: Digest, replace: bool) -> Digest:
    """An object store's write: one request, so atomic; never over another object
    unless ``replace`` (S3's ``If-None-Match``, no rename needed)."""
    try:
        if replace:
            path.put(payload)
            return digest
        try:
            path.put(payload, if_absent=True)
        except PreconditionFailed:
            if Digest.of(path.read_bytes()) != digest:
                raise StoreError(
                    f"{path}: already stored with other content; not overwritten"
                ) from None
    except (StorageError, FileNotFoundError) as err:
        raise StoreError(f"cannot write {path}: {err}") from None
    return digest


def _link_new(temporary: Path, path: Path, digest: Digest) -> None:
    """Put the temporary file at ``path`` unless ``path`` exists (then compare)."""
    try:
        os.link(temporary, path)
        return
    except FileExistsError:
        pass
    except OSError as err:
        if err.errno not in (errno.EPERM, errno.ENOTSUP, errno.EXDEV, errno.EMLINK):
            raise
        # No hard links on this file system: rename, unless the target exists.
        if not os.path.lexists(path):
            os.replace(temporary, path)
            return
    if not holds(path, digest):
        raise StoreError(f"{path}: already stored with other content; not overwritten")


def holds(path: Path, digest: Digest) -> bool:
    """Whether the local file at ``path`` has exactly the content of ``digest``, read as a
    stored file is (:func:`_open_stored`: StoreError naming a FIFO, a device, a directory or
    a symbolic link there) and only when its size is ``digest``'s: a file of another size is
    another content, so at most ``digest.size`` bytes are read."""
    fd, info = _open_stored(path)
    try:
        if info.st_size != digest.size:
            return False
        with open(fd, "rb", buffering=0, closefd=False) as handle:
            content = handle.read(digest.size + 1)  # one more: a file that grew meanwhile
    except OSError as err:
        raise StoreError(f"{path}: unreadable ({os_error_text(err)})") from None
    finally:
        os.close(fd)
    return Digest.of(content) == digest


def writable_target(path: Path) -> None:
    """Nothing, if ``path`` (local) is absent or a regular file; else StoreError naming it
    (a folder, a FIFO, a device, a socket or a symbolic link is never written over nor
    read to compare). For a target named by the user, checked before the work that makes
    its content."""
    try:
        info = os.lstat(path)
    except FileNotFoundError:
        return
    except OSError as err:
        raise StoreError(f"{path}: unreadable ({os_error_text(err)})") from None
    if stat.S_ISLNK(info.st_mode):
        raise StoreError(f"{path}: a symbolic link; not written through it")
    if not stat.S_ISREG(info.st_mode):
        raise StoreError(f"{path}: {file_kind(info.st_mode)}, not a regular file; not written")


def holds_other(path: Path | S3Path, payload: bytes) -> bool:
    """Whether a file with content other than ``payload`` is at ``path`` (False: absent or
    the same bytes). A local file is compared by :func:`holds` (special files refused)."""
    path = location(path)
    if isinstance(path, S3Path):
        try:
            return path.read_bytes() != payload
        except FileNotFoundError:
            return False
        except OSError as err:
            raise StoreError(f"{path}: unreadable ({os_error_text(err)})") from None
    if not os.path.lexists(path):
        return False
    return not holds(path, Digest.of(payload))


def make_folders(folder: Path) -> None:
    """Create the local ``folder`` and its missing parents, every existing component checked
    with ``lstat``: a symbolic link or a non-folder anywhere on the path is a StoreError
    naming it, so that no write below a store's or the workspace's root (resolved when it was
    named) is sent elsewhere by a link put inside it (a store's ``catalog/`` linked to an
    outside folder)."""
    folder = Path(os.path.abspath(folder))
    current = Path(folder.anchor)
    for part in folder.parts[1:]:
        current = current / part
        try:
            info = os.lstat(current)
        except FileNotFoundError:
            try:
                os.mkdir(current)
                continue
            except FileExistsError:  # made meanwhile by another writer: checked below
                info = os.lstat(current)
        if stat.S_ISLNK(info.st_mode):
            raise StoreError(
                f"{current}: a symbolic link on the path of a stored file; nothing written "
                "through it"
            )
        if not stat.S_ISDIR(info.st_mode):
            what = "a file" if stat.S_ISREG(info.st_mode) else file_kind(info.st_mode)
            raise StoreError(f"{current}: {what}, not a folder; nothing written in it")


def write_json(path: Path, value: Any, *, replace: bool = False) -> Digest:
    """Store :func:`ovtraj.store.records.json_text` of ``value`` (see :func:`write_bytes`)."""
    return write_bytes(path, (json_text(value) + "\n").encode("utf-8"), replace=replace)


def parquet_bytes(table: pa.Table) -> bytes:
    """The Parquet file of ``table``, with the stores' encoding (deterministic bytes)."""
    text = [
        f.name
        for f in table.schema
        if pa.types.is_string(f.type) or pa.types.is_large_string(f.type)
    ]
    floats = [f.name for f in table.schema if pa.types.is_floating(f.type)]
    sink = pa.BufferOutputStream()
    pq.write_table(
        table,
        sink,
        compression=PARQUET_COMPRESSION,
        compression_level=PARQUET_COMPRESSION_LEVEL,
        use_dictionary=text,
        use_byte_stream_split=floats or False,
    )
    return sink.getvalue().to_pybytes()


def write_parquet(path: Path, table: pa.Table, schema: pa.Schema) -> Digest:
    """Store ``table`` (exactly of ``schema``) as a Parquet file; returns its digest."""
    if not table.schema.equals(schema, check_metadata=False):
        raise ValueError(f"{path}: table does not have the declared schema")
    return write_bytes(path, parquet_bytes(table))


def read_bytes(path: Path, expected: Digest | None = None) -> bytes:
    """A stored file's content, checked against ``expected`` when given (a local file: a
    regular file whose size is checked before it is read, see the module notes)."""
    path = location(path)
    if isinstance(path, S3Path):
        try:
            payload = path.read_bytes()
        except FileNotFoundError:
            raise StoreError(f"{path}: missing") from None
        except OSError as err:
            raise StoreError(f"{path}: unreadable ({os_error_text(err)})") from None
    else:
        payload = _read_local(path, expected)
    if expected is not None:
        found = Digest.of(payload)
        if found.size != expected.size:
            raise StoreError(
                f"{path}: changed since it was stored ({found.size} bytes, "
                f"{expected.size} recorded)"
            )
        if found.sha256 != expected.sha256:
            raise StoreError(f"{path}: changed since it was stored (SHA-256 differs)")
    return payload


def json_data(text: str | bytes) -> Any:
    """The value of a JSON text read from a file (a plan, an OMM, a stored document),
    bounded: ``ValueError`` with one readable line for a text that does not parse, a
    number longer than ``json_number_max_chars`` characters (5000 digits would be ``inf``
    as a float and cost a quadratic conversion as an int) or beyond a float's range
    (``1e999``), ``NaN`` or ``Infinity`` (not JSON: :func:`json_text` never writes them),
    or arrays and objects nested deeper than ``json_max_depth`` (``configs/io_limits.yaml``;
    Python's parser would end in a RecursionError near 1000 levels)."""
    limits = given_settings()
    longest = limits.json_number_max_chars
    where = "json_number_max_chars of configs/io_limits.yaml"

    def number(kind: type) -> Any:
        def parse(literal: str) -> Any:
            if len(literal) > longest:
                raise ValueError(
                    f"a number of {len(literal)} characters, more than {longest} ({where})"
                )
            value = kind(literal)
            if kind is float and not math.isfinite(value):
                raise ValueError(f"{literal} is beyond a float's range")
            return value

        return parse

    def constant(name: str) -> Any:
        raise ValueError(f"{name} is not a JSON number (write a finite number or null)")

    too_deep = (
        f"arrays and objects nested deeper than {limits.json_max_depth} levels "
        "(json_max_depth of configs/io_limits.yaml)"
    )
    try:
        value = json.loads(
            text, parse_int=number(int), parse_float=number(float), parse_constant=constant
        )
    except json.JSONDecodeError as err:
        raise ValueError(f"not valid JSON: {err}") from None
    except RecursionError:
        raise ValueError(too_deep) from None
    if _depth(value) > limits.json_max_depth:
        raise ValueError(too_deep)
    return value


def _depth(value: Any) -> int:
    """How deep arrays and objects nest in the parsed JSON ``value`` (a scalar: 0), walked
    without recursion."""
    deepest, stack = 0, [(value, 1)]
    while stack:
        item, level = stack.pop()
        children = item.values() if isinstance(item, dict) else item
        if not isinstance(item, dict | list):
            continue
        deepest = max(deepest, level)
        stack.extend((child, level + 1) for child in children if isinstance(child, dict | list))
    return deepest


def read_json(path: Path, expected: Digest | None = None) -> Any:
    try:  # bounded: nesting depth and number length (json_data)
        return json_data(read_bytes(path, expected).decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as err:
        raise StoreError(f"{path}: unreadable JSON file ({err})") from None


class DecodedTables:
    """Arrow tables decoded from Parquet payloads, by the payload's SHA-256, least recently
    used first out beyond ``limit_bytes`` of Arrow memory. Arrow tables are immutable, so
    one can be handed to every reader of the same bytes."""

    def __init__(self, limit_bytes: int) -> None:
        self.limit_bytes = limit_bytes
        self._tables: OrderedDict[str, pa.Table] = OrderedDict()
        self._bytes = 0
        # Readers may be threads (Prefect's task runner, the threads runner).
        self._lock = threading.Lock()

    def get(self, sha256: str, payload: bytes) -> pa.Table:
        """The table ``payload`` (whose SHA-256 is ``sha256``) decodes to."""
        with self._lock:
            table = self._tables.get(sha256)
            if table is not None:
                self._tables.move_to_end(sha256)
                return table
        table = pq.read_table(pa.BufferReader(payload))  # outside the lock: readers overlap
        if table.nbytes > self.limit_bytes:
            return table
        with self._lock:
            if sha256 not in self._tables:
                self._tables[sha256] = table
                self._bytes += table.nbytes
                while self._bytes > self.limit_bytes:
                    self._bytes -= self._tables.popitem(last=False)[1].nbytes
        return table

    def clear(self) -> None:
        with self._lock:
            self._tables.clear()
            self._bytes = 0

    def __len__(self) -> int:
        return len(self._tables)

    @property
    def nbytes(self) -> int:
        """Arrow memory of the tables kept [bytes]."""
        return self._bytes


@functools.cache
def decoded_tables() -> DecodedTables:
    """This process's :class:`DecodedTables`, bounded by ``reads.decoded_tables_mib`` of
    ``configs/orchestration.yaml`` (:mod:`ovtraj.store.settings`)."""
    return DecodedTables(int(given_settings().decoded_tables_mib * BYTES_PER_MIB))


def read_table(
    path: Path, expected: Digest | None = None, schema: pa.Schema | None = None
) -> pa.Table:
    """A stored Parquet file as an Arrow table, checked (digest, then declared schema).

    The file is read and verified every time; with ``expected``, a payload decoded before
    in this process is not decoded again (:func:`decoded_tables`)."""
    payload = read_bytes(path, expected)
    try:
        if expected is None:
            table = pq.read_table(pa.BufferReader(payload))
        else:
            table = decoded_tables().get(expected.sha256, payload)
    except (OSError, pa.ArrowException) as err:
        why = " ".join(str(err).split())  # Arrow's text may span lines: one line here
        raise StoreError(f"{path}: unreadable Parquet file ({why})") from None
    if schema is not None and not table.schema.equals(schema, check_metadata=False):
        raise StoreError(f"{path}: columns or types differ from the declared schema")
    return table


def read_parquet(
    path: Path, expected: Digest | None = None, schema: pa.Schema | None = None
) -> pd.DataFrame:
    """A stored Parquet file as a data frame (see :func:`read_table`)."""
    return read_table(path, expected, schema).to_pandas()


def remove_orphans(directory: Path) -> list[Path]:
    """Remove the temporary files that interrupted writes left under ``directory``.

    Call it only when no other process writes there (the caller holds the lock).
    """
    directory = location(directory)
    if isinstance(directory, S3Path):
        return []  # an object store's writes leave no temporary object
    return [p for p in sorted(directory.rglob(f".*{TEMPORARY_SUFFIX}")) if remove_file(p)]


def remove_file(path: Path) -> bool:
    """Remove a file that is not (or no longer) stored; False if it was not there."""
    try:
        location(path).unlink()
    except FileNotFoundError:
        return False
    except OSError as err:
        raise StoreError(f"cannot remove {path}: {os_error_text(err)}") from None
    return True


def tree_bytes(directory: Path | S3Path, seen: set[tuple[int, int]] | None = None) -> int | None:
    """Bytes of the files under a local ``directory``; a file hard-linked from another run
    (adopted batches) counts once per ``seen`` set. None on an object store."""
    if isinstance(directory, S3Path):
        return None
    total = 0
    for folder, _, names in os.walk(directory):
        for name in names:
            try:
                stat = os.lstat(os.path.join(folder, name))
            except OSError:
                continue  # removed meanwhile
            if seen is not None:
                if (stat.st_dev, stat.st_ino) in seen:
                    continue
                seen.add((stat.st_dev, stat.st_ino))
            total += stat.st_size
    return total
