"""Where stored files live: a local path, or an object store (``s3://bucket/prefix``).

The stores address their files through a small path-like interface: ``/``, ``name``,
``stem``, ``suffix``, ``parent``, ``exists``/``is_file``/``is_dir``, ``iterdir``,
``glob``/``rglob``, ``read_bytes``, ``unlink``, ``resolve``. A local location is a
:class:`pathlib.Path`; an object-store location is an :class:`S3Path`, which offers
the same subset over the S3 API (``boto3``; the endpoint, region and credentials from
the standard ``AWS_ENDPOINT_URL``, ``AWS_DEFAULT_REGION``, ``AWS_ACCESS_KEY_ID`` ...
variables or files). :func:`location` turns a string into either.

An object store has no rename, no hard link and no file lock. What the stores need
of them is done with S3's conditional writes instead (:mod:`ovtraj.store.files`,
:mod:`ovtraj.store.locks`): a stored file is created only if absent (``If-None-Match: *``),
the mutable index is replaced only if unchanged since read (``If-Match``), and locks
are lease objects that their holder renews.
"""

from __future__ import annotations

import fnmatch
import functools
import os
from collections.abc import Iterator
from pathlib import Path, PurePosixPath
from typing import Any

from ovtraj.errors import ConfigError
from ovtraj.store.settings import given_settings

__all__ = ["PreconditionFailed", "S3Path", "StorageError", "location"]

SCHEME = "s3://"


class StorageError(OSError):
    """An object-store request that failed (the message names the key and the cause)."""


def location(value: str | os.PathLike[str] | S3Path) -> Path | S3Path:
    """A store location: an :class:`S3Path` for ``s3://`` URLs, else a local path."""
    if isinstance(value, S3Path):
        return value
    text = str(value)
    if text.startswith(SCHEME):
        return S3Path.from_url(text)
    return Path(value)


@functools.lru_cache(maxsize=1)
def _client() -> Any:
    import boto3
    from botocore.config import Config

    # Bounded: a request never hangs (every figure of the retry and time-out policy
    # is boto3's standard mode, plus the two waits of configs/io_limits.yaml).
    settings = given_settings()
    config = Config(
        retries={"mode": "standard"},
        connect_timeout=settings.s3_connect_timeout_s,
        read_timeout=settings.s3_read_timeout_s,
    )
    return boto3.client("s3", config=config)


def _code(err: Exception) -> str | None:
    """The S3 error code of a botocore error (None for other errors)."""
    response = getattr(err, "response", None)
    return response.get("Error", {}).get("Code") if isinstance(response, dict) else None


def _error(err: Exception, url: str) -> StorageError:
    return StorageError(f"{url}: {_code(err) or type(err).__name__}: {err}")


class PreconditionFailed(StorageError):
    """A conditional write whose condition did not hold (the object exists / changed)."""


class S3Path:
    """An object key (or a key prefix, as a folder) in a bucket; immutable."""

    __slots__ = ("_is_file", "bucket", "key")

    def __init__(self, bucket: str, key: str = "", *, is_file: bool | None = None) -> None:
        self.bucket = bucket
        self.key = "/".join(part for part in key.split("/") if part not in ("", "."))
        self._is_file = is_file

    @classmethod
    def from_url(cls, url: str) -> S3Path:
        rest = url.removeprefix(SCHEME)
        bucket, _, key = rest.partition("/")
        if not bucket:  # ConfigError, a ValueError: the commands' one line, exit 2
            raise ConfigError(
                ["an object-store location names its bucket: s3://BUCKET[/PREFIX]"], url
            )
        return cls(bucket, key)

    # -- pure path ------------------------------------------------------------------------
    def __str__(self) -> str:
        return f"{SCHEME}{self.bucket}/{self.key}" if self.key else f"{SCHEME}{self.bucket}"

    def __repr__(self) -> str:
        return f"S3Path({str(self)!r})"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, S3Path) and (self.bucket, self.key) == (other.bucket, other.key)

    def __hash__(self) -> int:
        return hash((self.bucket, self.key))

    def __lt__(self, other: S3Path) -> bool:
        return (self.bucket, self.key) < (other.bucket, other.key)

    def __truediv__(self, part: str | os.PathLike[str]) -> S3Path:
        return S3Path(self.bucket, f"{self.key}/{part}")

    @property
    def name(self) -> str:
        return PurePosixPath(self.key).name

    @property
    def stem(self) -> str:
        return PurePosixPath(self.key).stem

    @property
    def suffix(self) -> str:
        return PurePosixPath(self.key).suffix

    @property
    def parent(self) -> S3Path:
        return S3Path(self.bucket, str(PurePosixPath(self.key).parent))

    @property
    def parts(self) -> tuple[str, ...]:
        return PurePosixPath(self.key).parts

    def with_name(self, name: str) -> S3Path:
        return self.parent / name

    def relative_to(self, other: S3Path) -> PurePosixPath:
        if other.bucket != self.bucket:
            raise ValueError(f"{self} is not under {other}")
        return PurePosixPath(self.key).relative_to(other.key or ".")

    def resolve(self) -> S3Path:
        return self

    def expanduser(self) -> S3Path:
        return self

    def is_absolute(self) -> bool:
        return True

    def mkdir(self, parents: bool = False, exist_ok: bool = False) -> None:
        """Folders are key prefixes: nothing to create."""

    # -- requests -------------------------------------------------------------------------
    def _keys(self, prefix: str, delimiter: str = "") -> Iterator[dict[str, Any]]:
        arguments: dict[str, Any] = {"Bucket": self.bucket, "Prefix": prefix}
        if delimiter:
            arguments["Delimiter"] = delimiter
        try:
            for page in _client().get_paginator("list_objects_v2").paginate(**arguments):
                yield from ({"file": o["Key"]} for o in page.get("Contents", []))
                yield from ({"folder": p["Prefix"]} for p in page.get("CommonPrefixes", []))
        except Exception as err:
            raise _error(err, str(self)) from None

    def _folder_prefix(self) -> str:
        return f"{self.key}/" if self.key else ""

    def is_file(self) -> bool:
        if self._is_file is not None:
            return self._is_file
        return self.head() is not None

    def is_dir(self) -> bool:
        return next(iter(self._keys(self._folder_prefix())), None) is not None

    def exists(self) -> bool:
        return self.is_file() or self.is_dir()

    def iterdir(self) -> Iterator[S3Path]:
        for entry in self._keys(self._folder_prefix(), "/"):
            if "file" in entry:
                yield S3Path(self.bucket, entry["file"], is_file=True)
            else:
                yield S3Path(self.bucket, entry["folder"], is_file=False)

    def rglob(self, pattern: str) -> Iterator[S3Path]:
        for entry in self._keys(self._folder_prefix()):
            path = S3Path(self.bucket, entry["file"], is_file=True)
            if fnmatch.fnmatchcase(path.name, pattern):
                yield path

    def glob(self, pattern: str) -> Iterator[S3Path]:
        """Files matching ``pattern`` segment by segment (``*`` stays within a segment)."""
        wanted = pattern.split("/")
        for entry in self._keys(self._folder_prefix()):
            path = S3Path(self.bucket, entry["file"], is_file=True)
            parts = path.relative_to(self).parts
            if len(parts) == len(wanted) and all(
                fnmatch.fnmatchcase(p, w) for p, w in zip(parts, wanted, strict=True)
            ):
                yield path

    def head(self) -> str | None:
        """The object's ETag, or None if there is no object at this key."""
        try:
            return _client().head_object(Bucket=self.bucket, Key=self.key)["ETag"]
        except Exception as err:
            if _code(err) in ("404", "NoSuchKey"):
                return None
            raise _error(err, str(self)) from None

    def read_bytes(self) -> bytes:
        return self.read_with_etag()[0]

    def read_with_etag(self) -> tuple[bytes, str]:
        try:
            answer = _client().get_object(Bucket=self.bucket, Key=self.key)
            return answer["Body"].read(), answer["ETag"]
        except Exception as err:
            if _code(err) in ("NoSuchKey", "404"):
                raise FileNotFoundError(str(self)) from None
            raise _error(err, str(self)) from None

    def read_text(self, encoding: str = "utf-8") -> str:
        return self.read_bytes().decode(encoding)

    def put(self, payload: bytes, *, if_absent: bool = False, if_match: str | None = None) -> str:
        """Store ``payload``; returns its ETag. ``if_absent``: only if no object is there;
        ``if_match``: only if the object's ETag is still that (else PreconditionFailed)."""
        arguments: dict[str, Any] = {"Bucket": self.bucket, "Key": self.key, "Body": payload}
        if if_absent:
            arguments["IfNoneMatch"] = "*"
        if if_match is not None:
            arguments["IfMatch"] = if_match
        try:
            return _client().put_object(**arguments)["ETag"]
        except Exception as err:
            if _code(err) in ("PreconditionFailed", "ConditionalRequestConflict"):
                raise PreconditionFailed(f"{self}: {_code(err)}") from None
            raise _error(err, str(self)) from None

    def unlink(self, missing_ok: bool = False) -> None:
        if not missing_ok and self.head() is None:
            raise FileNotFoundError(str(self))
        try:
            _client().delete_object(Bucket=self.bucket, Key=self.key)
        except Exception as err:
            raise _error(err, str(self)) from None
