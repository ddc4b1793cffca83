"""Tamper evidence: an HMAC-SHA256 seal on every manifest and marker, under a key kept
outside the store (``OVTRAJ_STORE_KEY``).

The stores' checksums (:mod:`ovtraj.store.files`) detect accidents: a file changed after it was
stored no longer matches the size and SHA-256 its marker records. They cannot detect
tampering, since whoever can write a data file can also write its marker with the new
digest. With a key configured, every manifest and marker the project writes carries a
sibling field ``"hmac"``: the HMAC-SHA256 (hex) of the document's other fields as
canonical JSON (:func:`canonical_json`). A marker lists the SHA-256 of each of its data
files, and every read checks a data file against that digest, so an authentic marker
authenticates its data files too.

- *Key:* the text of the environment variable ``OVTRAJ_STORE_KEY`` (UTF-8), at least
  ``store_key.min_bytes`` of ``configs/orchestration.yaml`` long. It is never written
  into a store and never printed.
- *Writing* (:func:`sealed`): with a key, the document plus its ``"hmac"``; without
  one, the document unchanged (the same bytes as a store written before seals existed).
  The seal depends only on the content and the key: the same inputs and key write the
  same bytes.
- *Reading* (:func:`authenticated`): with a key, a document without a seal or with a
  wrong one is refused (:class:`TamperedError`, a :class:`~ovtraj.store.files.StoreError`
  naming the file): it was changed without the key, sealed with another key, or written
  while no key was configured (such a store cannot be authenticated). Without a key the
  seal is not checked. Readers get the document without its seal.
- *Shipped reference data* (:func:`ovtraj.paths.reference_dir`, e.g. the launch fit and
  the mission chain's reference) is part of the code, trusted as the code is: it is
  neither sealed nor checked, so it reads under any key and keeps its bytes.
"""

from __future__ import annotations

import hashlib
import hmac
import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ovtraj.paths import reference_dir
from ovtraj.store.backends import S3Path
from ovtraj.store.environment_block import environment_problem
from ovtraj.store.files import Digest, StoreError, read_json, write_json
from ovtraj.store.records import plain
from ovtraj.store.settings import given_settings

__all__ = [
    "SEAL_FIELD",
    "STORE_KEY_ENV",
    "TamperedError",
    "authenticated",
    "canonical_json",
    "read_authenticated",
    "seal_problem",
    "sealed",
    "store_key",
    "write_sealed",
]

STORE_KEY_ENV = "OVTRAJ_STORE_KEY"
SEAL_FIELD = "hmac"


class TamperedError(StoreError):
    """A manifest or marker whose seal is missing or wrong under the configured key (named)."""


def store_key() -> bytes | None:
    """The configured key (``OVTRAJ_STORE_KEY`` as UTF-8 bytes), or None when it is unset.

    A key shorter than ``store_key.min_bytes`` [bytes] is a :class:`ConfigError`: an
    empty or short key (e.g. ``$(cat missing-file)``) must not pass for protection.
    """
    text = os.environ.get(STORE_KEY_ENV)
    if text is None:
        return None
    from ovtraj.errors import ConfigError

    key = text.encode("utf-8", "surrogateescape")
    least = given_settings().store_key_min_bytes
    if len(key) < least:
        # The key's length only, never its text.
        raise ConfigError(
            [f"{STORE_KEY_ENV} has {len(key)} bytes; a store key needs at least {least}"],
            "the environment",
        )
    return key


def _shipped(path: Path | S3Path) -> bool:
    """Whether ``path`` is in the shipped reference data. Compared by name, links not
    followed: a link in a store to a shipped file is still a file of the store."""
    if isinstance(path, S3Path):
        return False
    shipped = os.path.abspath(reference_dir())
    return os.path.commonpath([shipped, os.path.abspath(path)]) == shipped


def _key_for(path: Path | S3Path) -> bytes | None:
    """The key that seals ``path``: none for shipped reference data."""
    return None if _shipped(path) else store_key()


def canonical_json(document: Mapping[str, Any]) -> bytes:
    """The bytes a seal covers: the document (its seal left out) as compact JSON with
    sorted keys, ASCII only; the same for the document written and the one read back."""
    rest = {k: v for k, v in document.items() if k != SEAL_FIELD}
    text = json.dumps(
        plain(rest), sort_keys=True, separators=(",", ":"), ensure_ascii=True, allow_nan=False
    )
    return text.encode("ascii")


def _seal(key: bytes, document: Mapping[str, Any]) -> str:
    return hmac.new(key, canonical_json(document), hashlib.sha256).hexdigest()


def sealed(path: Path | S3Path, document: Mapping[str, Any]) -> dict[str, Any]:
    """``document`` to be written at ``path``: with a key configured, sealed (``"hmac"``
    last); without one, as it is. A seal it carried (a manifest read back) is dropped."""
    content = {k: v for k, v in document.items() if k != SEAL_FIELD}
    key = _key_for(path)
    if key is None:
        return content
    return {**content, SEAL_FIELD: _seal(key, content)}


def seal_problem(path: Path | S3Path, document: Any) -> str | None:
    """Why ``document`` (read from ``path``) is not authentic under the configured key, in
    one line naming the file; None when it is, or when no key is configured."""
    if not isinstance(document, Mapping):
        return None  # not a document: the caller's own check refuses it
    key = _key_for(path)
    if key is None:
        return None
    found = document.get(SEAL_FIELD)
    if found is None:
        return (
            f"{path}: tampered: no HMAC while {STORE_KEY_ENV} is set (changed, or written "
            "without the key: such a file cannot be authenticated)"
        )
    expected = _seal(key, document)
    if not (isinstance(found, str) and found.isascii() and hmac.compare_digest(found, expected)):
        return f"{path}: tampered: its HMAC does not match (changed, or sealed with another key)"
    return None


def authenticated(path: Path | S3Path, document: Any) -> Any:
    """``document`` (read from ``path``) without its seal, once the seal is checked with a
    key configured (:class:`TamperedError` naming the file). Every reader of a manifest or
    marker comes here, so its environment block is checked here too
    (:func:`ovtraj.store.environment_block.environment_problem`, a StoreError)."""
    problem = seal_problem(path, document)
    if problem is not None:
        raise TamperedError(problem)
    problem = environment_problem(path, document)
    if problem is not None:
        raise StoreError(problem)
    if isinstance(document, Mapping) and SEAL_FIELD in document:
        return {k: v for k, v in document.items() if k != SEAL_FIELD}
    return document


def write_sealed(
    path: Path | S3Path, document: Mapping[str, Any], *, replace: bool = False
) -> Digest:
    """Store a manifest or marker (:func:`ovtraj.store.files.write_json` of :func:`sealed`)."""
    return write_json(path, sealed(path, document), replace=replace)


def read_authenticated(path: Path | S3Path, expected: Digest | None = None) -> Any:
    """A stored manifest or marker (:func:`ovtraj.store.files.read_json`), :func:`authenticated`."""
    return authenticated(path, read_json(path, expected))
