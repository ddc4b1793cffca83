"""Element sets from an http(s) URL: one deadline for the whole fetch, checked
redirects, and a content-addressed cache keyed by the URL that served the bytes.

The cache lives in the workspace next to the run store
(``<workspace>/target_sources/``, see :func:`default_cache_dir`):

* ``blobs/<sha256>``: the bytes of every response, named by their SHA-256 and
  never changed (:func:`ovtraj.store.files.write_bytes`);
* ``urls/<sha256 of the URL served>.json``: the latest fetch that URL served,
  ``{"url", "requested_url", "sha256", "bytes", "fetched_utc"}`` (``url`` served the
  bytes; ``requested_url`` was asked for, another one when it redirected), replaced
  atomically on each fetch.

A URL fetched less than ``url_cache_max_age_h`` ago is read from its blob, checked
against its digest, without a request (catalogues such as CelesTrak refresh their
element sets a few times a day; fetching the same set more often only loads the
server and changes nothing). A URL that redirects is asked again each time (a cached
redirect would outlive the server's say and ``url_redirect_hosts``); the URL it leads
to is read from the cache when fetched recently enough. The scenario itself then
carries the element set read (``docs/targets.md``), so a replay of a stored run reads
neither the network nor the cache.

Bounds, all from ``target.source_settings``:

* ``url_timeout_s`` bounds the whole fetch: the connection, every redirect, the
  headers and the body. The fetch runs in a thread the caller waits for no longer, and
  a watchdog shuts its sockets down when the time is up, so that a server sending one
  byte a second (each read returning in time) is cut off there too;
* a redirect keeps the scheme, except http -> https (never ``ftp:``, ``file:`` or
  another), and the URL's host, unless the new host is listed in
  ``url_redirect_hosts``; at most urllib's ``HTTPRedirectHandler.max_redirections``
  redirects, never the same URL twice;
* at most ``url_max_mib`` of body (a larger ``Content-Length`` is refused unread).

Every failure is one :class:`ConfigError` naming the URL: unreachable host, HTTP
error status, not done within ``url_timeout_s``, a refused redirect, a download above
``url_max_mib`` or bytes that are not UTF-8 text.
"""

from __future__ import annotations

import functools
import hashlib
import http.client
import socket
import threading
import time
import urllib.error
import urllib.parse
import urllib.request
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from ovtraj import __version__
from ovtraj.config.io_limits import echoed
from ovtraj.config.target import TargetSourceSettings
from ovtraj.errors import ConfigError
from ovtraj.store.files import Digest, StoreError, read_bytes, read_json, write_bytes, write_json
from ovtraj.units import S_PER_HOUR

__all__ = ["default_cache_dir", "fetch_text", "is_url"]

_SCHEMES = ("http://", "https://")
_CHUNK_BYTES = 1 << 16
_REDIRECTS = {301, 302, 303, 307, 308}
# The standard library's own bound on a chain of redirects (10).
_MAX_REDIRECTS = urllib.request.HTTPRedirectHandler.max_redirections


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
    """The bytes ``url`` served at its latest fetch if younger than ``max_age_s`` and intact."""
    index = cache_dir / "urls" / f"{_url_key(url)}.json"
    if max_age_s <= 0.0 or not index.is_file():
        return None
    try:
        entry = read_json(index)
        fetched = datetime.fromisoformat(entry["fetched_utc"])
        if (datetime.now(UTC) - fetched).total_seconds() > max_age_s or entry["url"] != url:
            return None
        digest = Digest.from_json(entry)
        return read_bytes(cache_dir / "blobs" / digest.sha256, digest)
    except (StoreError, KeyError, TypeError, ValueError, OverflowError):
        return None  # a damaged entry is fetched again


class _Deadline:
    """One deadline for a whole fetch [s]: when it passes, every socket the fetch opened
    is shut down, so that a blocked read, TLS handshake or proxy answer returns at once
    (a socket time-out bounds each wait, not their sum)."""

    def __init__(self, seconds: float) -> None:
        self.seconds = seconds
        self._end = time.monotonic() + seconds
        self._lock = threading.Lock()
        self._sockets: list[socket.socket] = []
        self.passed = False
        self._timer = threading.Timer(seconds, self.expire)
        self._timer.daemon = True

    def start(self) -> None:
        self._timer.start()

    def cancel(self) -> None:
        self._timer.cancel()

    def time_left(self) -> float:
        """Seconds left [s], > 0; TimeoutError once passed (a time-out of 0 would make a
        socket non-blocking, not bounded)."""
        left = self._end - time.monotonic()
        if self.passed or left <= 0.0:
            raise TimeoutError
        return left

    def watch(self, sock: socket.socket) -> None:
        """Shut ``sock`` down when the deadline passes (at once if it has)."""
        with self._lock:
            self._sockets.append(sock)
            if self.passed:
                _shut(sock)

    def expire(self) -> None:
        """Shut every watched socket down, and every socket watched from now on."""
        with self._lock:
            self.passed = True
            for sock in self._sockets:
                _shut(sock)


def _shut(sock: socket.socket) -> None:
    try:
        # the plain socket's shutdown, also of a TLS socket: the TLS socket's own would
        # drop its TLS state under the thread reading it
        socket.socket.shutdown(sock, socket.SHUT_RDWR)
    except OSError:
        pass  # closed already (or detached by the TLS wrap, which is watched itself)


class _Watched:
    """An ``http.client`` connection whose sockets the deadline watches from their
    creation (a proxy's tunnel included) and whose connection waits the time left."""

    def __init__(self, *args: Any, deadline: _Deadline, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._deadline = deadline
        create = self._create_connection

        def watched(*call: Any, **options: Any) -> socket.socket:
            sock = create(*call, **options)
            deadline.watch(sock)
            return sock

        self._create_connection = watched

    def connect(self) -> None:
        self.timeout = self._deadline.time_left()
        super().connect()


class _WatchedHTTP(_Watched, http.client.HTTPConnection):
    pass


class _WatchedHTTPS(_Watched, http.client.HTTPSConnection):
    def connect(self) -> None:
        # http.client.HTTPSConnection.connect, with the handshake after the TLS socket is
        # watched (the wrap detaches the plain socket the deadline watched so far)
        self.timeout = self._deadline.time_left()
        http.client.HTTPConnection.connect(self)
        host = self._tunnel_host or self.host
        self.sock = self._context.wrap_socket(
            self.sock, server_hostname=host, do_handshake_on_connect=False
        )
        self._deadline.watch(self.sock)
        self.sock.do_handshake()


class _HTTPHandler(urllib.request.HTTPHandler):
    def __init__(self, deadline: _Deadline) -> None:
        super().__init__()
        self._deadline = deadline

    def http_open(self, req: urllib.request.Request) -> http.client.HTTPResponse:
        return self.do_open(functools.partial(_WatchedHTTP, deadline=self._deadline), req)


class _HTTPSHandler(urllib.request.HTTPSHandler):
    def __init__(self, deadline: _Deadline) -> None:
        super().__init__()
        self._deadline = deadline

    def https_open(self, req: urllib.request.Request) -> http.client.HTTPResponse:
        watched = functools.partial(_WatchedHTTPS, deadline=self._deadline)
        return self.do_open(watched, req, context=self._context)


class _NoRedirect(urllib.request.HTTPRedirectHandler):
    """A redirect comes back as an HTTPError, its body unread: :func:`_fetch` checks it."""

    def redirect_request(self, *args: Any) -> None:
        return None


def _redirect_target(
    requested: str, current: str, location: str | None, settings: TargetSourceSettings
) -> str:
    """The URL a redirect of ``current`` leads to, if allowed; ConfigError otherwise."""
    if not location:
        raise ConfigError(["a redirect without a Location"], echoed(requested))
    target = urllib.parse.urljoin(current, location.strip())
    old, new = urllib.parse.urlsplit(current), urllib.parse.urlsplit(target)
    if new.scheme != old.scheme and (old.scheme, new.scheme) != ("http", "https"):
        raise ConfigError(
            [
                f"redirected to {echoed(target)}: a redirect to another scheme is refused "
                "(only http -> https)"
            ],
            echoed(requested),
        )
    first = urllib.parse.urlsplit(requested)
    own = (first.hostname or "").lower()
    host = (new.hostname or "").lower()
    # The URL's own server is its host AND port (another port on the same host may be
    # another program); http -> https on the schemes' default ports is the same server.
    ports = (_port(first), _port(new))
    same_server = host == own and (ports[0] == ports[1] or ports == (80, 443))
    if not same_server and host not in settings.url_redirect_hosts:
        where = host if host != own else f"{host} port {ports[1]}"
        raise ConfigError(
            [
                f"redirected to another host, {echoed(where)} ({echoed(target)}): refused, "
                "not in url_redirect_hosts"
            ],
            echoed(requested),
        )
    return target


_DEFAULT_PORTS = {"http": 80, "https": 443}  # RFC 9110 sec. 4.2


def _port(url: urllib.parse.SplitResult) -> int | None:
    """The port ``url`` is served on: its own, else its scheme's default (a port that does
    not parse is left to the request, which refuses it)."""
    try:
        return url.port or _DEFAULT_PORTS.get(url.scheme)
    except ValueError:
        return None


def _body(response: http.client.HTTPResponse, where: str, settings: TargetSourceSettings) -> bytes:
    """The response body, at most ``url_max_mib``; ConfigError naming the URL beyond."""
    max_bytes = settings.max_bytes
    too_large = ConfigError([f"larger than url_max_mib = {settings.url_max_mib:g} MiB"], where)
    declared = response.headers.get("Content-Length", "").strip()
    if declared.isdigit() and int(declared) > max_bytes:
        raise too_large
    chunks, size = [], 0
    while chunk := response.read(_CHUNK_BYTES):
        size += len(chunk)
        if size > max_bytes:
            raise too_large
        chunks.append(chunk)
    return b"".join(chunks)


def _fetch(
    url: str,
    settings: TargetSourceSettings,
    deadline: _Deadline,
    cache_dir: Path,
    max_age_s: float,
) -> tuple[bytes, str, bool]:
    """The bytes of ``url`` (redirects followed where allowed), the URL that served them,
    and whether they came from the cache (a redirect's target fetched recently)."""
    where = echoed(url)
    opener = urllib.request.build_opener(
        _HTTPHandler(deadline), _HTTPSHandler(deadline), _NoRedirect()
    )
    current, seen = url, {url}
    for _ in range(_MAX_REDIRECTS + 1):
        request = urllib.request.Request(current, headers={"User-Agent": f"ovtraj/{__version__}"})
        try:
            response = opener.open(request, timeout=deadline.time_left())
        except urllib.error.HTTPError as err:
            if err.code not in _REDIRECTS:
                raise
            location = err.headers.get("Location")
            err.close()  # the redirect's body is not read
            current = _redirect_target(url, current, location, settings)
            if current in seen:
                raise ConfigError([f"a redirect loop back to {echoed(current)}"], where) from None
            seen.add(current)
            payload = _cached(current, cache_dir, max_age_s)
            if payload is not None:
                return payload, current, True
            continue
        with response:
            return _body(response, where, settings), current, False
    raise ConfigError([f"more than {_MAX_REDIRECTS} redirects"], where)


def _download(
    url: str, settings: TargetSourceSettings, cache_dir: Path, max_age_s: float
) -> tuple[bytes, str, bool]:
    """:func:`_fetch` within ``url_timeout_s``; ConfigError naming the URL on any failure."""
    where = echoed(url)
    timeout_s = settings.url_timeout_s
    timed_out = ConfigError([f"no answer within url_timeout_s = {timeout_s:g} s"], where)
    deadline = _Deadline(timeout_s)
    outcome: dict[str, Any] = {}

    def work() -> None:
        try:
            outcome["value"] = _fetch(url, settings, deadline, cache_dir, max_age_s)
        except BaseException as err:  # handed to the caller's thread
            outcome["error"] = err

    # The fetch runs in a thread the caller waits for no longer than the deadline:
    # name resolution is not bounded by a socket time-out, the watchdog ends the rest.
    worker = threading.Thread(target=work, name="ovtraj-url-fetch", daemon=True)
    deadline.start()
    try:
        worker.start()
        worker.join(timeout_s)
    finally:
        deadline.cancel()
        if worker.is_alive():  # given up (or interrupted): its sockets, also any it opens
            deadline.expire()
    if worker.is_alive() or deadline.passed:
        raise timed_out
    if "value" in outcome:
        return outcome["value"]
    err = outcome["error"]
    if isinstance(err, ConfigError):
        raise err
    if isinstance(err, urllib.error.HTTPError):
        if err.code in _REDIRECTS:  # urllib's own, should one get through
            raise ConfigError([f"HTTP redirect {err.code} not followed"], where) from None
        raise ConfigError([f"HTTP error {err.code} {echoed(str(err.reason))}"], where) from None
    if isinstance(err, urllib.error.URLError):
        if isinstance(err.reason, TimeoutError):
            raise timed_out from None
        raise ConfigError([f"unreachable ({echoed(str(err.reason))})"], where) from None
    if isinstance(err, TimeoutError):
        raise timed_out from None
    if isinstance(err, (OSError, ValueError, http.client.HTTPException)):
        # connection reset, malformed URL or response
        raise ConfigError([f"unreachable ({echoed(str(err))})"], where) from None
    raise err


def fetch_text(
    url: str,
    *,
    settings: TargetSourceSettings,
    cache_dir: Path | None = None,
) -> str:
    """The text at ``url``: from the cache when fetched recently enough, else downloaded
    (and cached under the URL that served it) within ``settings.url_timeout_s`` [s] for
    the whole fetch; see the module notes."""
    url = url.strip()
    if not is_url(url):
        raise ConfigError(["not an http:// or https:// address"], echoed(url))
    cache_dir = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    max_age_s = settings.url_cache_max_age_h * S_PER_HOUR
    payload = _cached(url, cache_dir, max_age_s)
    if payload is None:
        payload, served, from_cache = _download(url, settings, cache_dir, max_age_s)
        if not from_cache:
            _store(cache_dir, url, served, payload)
    try:
        return payload.decode("utf-8")
    except UnicodeDecodeError:
        raise ConfigError(["the response is not UTF-8 text"], echoed(url)) from None


def _store(cache_dir: Path, requested: str, served: str, payload: bytes) -> None:
    """The payload's blob, and the record of the URL that served it (naming both)."""
    try:
        digest = write_bytes(cache_dir / "blobs" / Digest.of(payload).sha256, payload)
        entry = {
            "url": served,
            "requested_url": requested,
            **digest.to_json(),
            "fetched_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        }
        write_json(cache_dir / "urls" / f"{_url_key(served)}.json", entry, replace=True)
    except StoreError as err:
        raise ConfigError([f"cannot cache the download: {err}"], echoed(requested)) from None
