"""Element sets from an http(s) URL, with a time-out and a content-addressed cache.

The cache lives in the workspace next to the run store
(``<workspace>/target_sources/``, see :func:`default_cache_dir`):

* ``blobs/<sha256>``: the bytes of every response, named by their SHA-256 and
  never changed (:func:`ovtraj.files.write_bytes`);
* ``urls/<sha256 of the URL>.json``: the URL's latest fetch, ``{"url", "sha256",
  "bytes", "fetched_utc"}``, replaced atomically on each fetch.

A URL fetched less than ``url_cache_max_age_h`` ago is read from its blob, checked
against its digest, without a request (catalogues such as CelesTrak refresh their
element sets a few times a day; fetching the same set more often only loads the
server and changes nothing). The scenario itself
then carries the element set read (``docs/targets.md``), so a replay of a stored
run reads neither the network nor the cache.

Every failure is one :class:`ConfigError` naming the URL: unreachable host, HTTP
error status, no answer within ``url_timeout_s``, a download above ``url_max_mib``
or bytes that are not UTF-8 text.
"""

from __future__ import annotations

import hashlib
import socket
import time
import urllib.error
import urllib.request
from datetime import UTC, datetime
from pathlib import Path

from ovtraj import __version__
from ovtraj.config.base import ConfigError
from ovtraj.files import Digest, StoreError, read_bytes, read_json, write_bytes, write_json

__all__ = ["default_cache_dir", "fetch_text", "is_url"]

_SCHEMES = ("http://", "https://")
_CHUNK_BYTES = 1 << 16
_BYTES_PER_MIB = 1 << 20
_SECONDS_PER_HOUR = 3600.0


def is_url(source: str) -> bool:
    """Whether ``source`` is an http(s) address."""
    return str(source).strip().lower().startswith(_SCHEMES)


def default_cache_dir() -> Path:
    """``<workspace>/target_sources``: beside the run store (``<workspace>/runs``)."""
    from ovtraj import paths

    return paths.workspace() / "target_sources"


def _url_key(url: str) -> str:
    return hashlib.sha256(url.encode("utf-8")).hexdigest()


def _cached(url: str, cache_dir: Path, max_age_s: float) -> bytes | None:
    """The bytes of the URL's latest fetch if younger than ``max_age_s`` and intact."""
    index = cache_dir / "urls" / f"{_url_key(url)}.json"
    if max_age_s <= 0.0 or not index.is_file():
        return None
    try:
        entry = read_json(index)
        fetched = datetime.fromisoformat(entry["fetched_utc"])
        if (datetime.now(UTC) - fetched).total_seconds() > max_age_s or entry["url"] != url:
            return None
        digest = Digest(int(entry["bytes"]), str(entry["sha256"]))
        return read_bytes(cache_dir / "blobs" / digest.sha256, digest)
    except (StoreError, KeyError, TypeError, ValueError):
        return None  # a damaged entry is fetched again


def _download(url: str, timeout_s: float, max_bytes: int) -> bytes:
    """The response body; ConfigError naming the URL on any failure."""
    request = urllib.request.Request(url, headers={"User-Agent": f"ovtraj/{__version__}"})
    deadline = time.monotonic() + timeout_s
    try:
        with urllib.request.urlopen(request, timeout=timeout_s) as response:
            chunks, size = [], 0
            while chunk := response.read(_CHUNK_BYTES):
                size += len(chunk)
                if size > max_bytes:
                    raise ConfigError(
                        [f"larger than url_max_mib = {max_bytes / _BYTES_PER_MIB:g} MiB"], url
                    )
                if time.monotonic() > deadline:
                    raise TimeoutError
                chunks.append(chunk)
            return b"".join(chunks)
    except urllib.error.HTTPError as err:
        raise ConfigError([f"HTTP error {err.code} {err.reason}"], url) from None
    except TimeoutError:
        raise ConfigError([f"no answer within url_timeout_s = {timeout_s:g} s"], url) from None
    except urllib.error.URLError as err:
        if isinstance(err.reason, (TimeoutError, socket.timeout)):
            raise ConfigError([f"no answer within url_timeout_s = {timeout_s:g} s"], url) from None
        raise ConfigError([f"unreachable ({err.reason})"], url) from None
    except (OSError, ValueError) as err:  # connection reset, malformed URL or response
        raise ConfigError([f"unreachable ({err})"], url) from None


def fetch_text(
    url: str,
    *,
    timeout_s: float,
    cache_max_age_h: float,
    max_mib: float,
    cache_dir: Path | None = None,
) -> str:
    """The text at ``url``: from the cache when fetched recently enough, else downloaded
    (and cached). ``timeout_s`` bounds the wait for each answer [s]."""
    url = url.strip()
    cache_dir = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    payload = _cached(url, cache_dir, cache_max_age_h * _SECONDS_PER_HOUR)
    if payload is None:
        payload = _download(url, timeout_s, int(max_mib * _BYTES_PER_MIB))
        try:
            digest = write_bytes(cache_dir / "blobs" / Digest.of(payload).sha256, payload)
            entry = {
                "url": url,
                **digest.to_json(),
                "fetched_utc": datetime.now(UTC).isoformat(timespec="seconds"),
            }
            write_json(cache_dir / "urls" / f"{_url_key(url)}.json", entry, replace=True)
        except StoreError as err:
            raise ConfigError([f"cannot cache the download: {err}"], url) from None
    try:
        return payload.decode("utf-8")
    except UnicodeDecodeError:
        raise ConfigError(["the response is not UTF-8 text"], url) from None
