"""Plots embedded in text documents: a PNG as an RFC 2397 ``data:`` URI.

An HTML report or a Prefect markdown artifact that carries its images this way shows
them wherever it is opened (a remote Prefect UI, a mail attachment), with no path on
the machine that wrote them.
"""

from __future__ import annotations

import base64
from pathlib import Path

from ovtraj.store.backends import location
from ovtraj.store.files import read_bytes

__all__ = ["png_data_uri"]


def png_data_uri(path: Path | str) -> str:
    """The PNG file at ``path`` as ``data:image/png;base64,...`` (RFC 2397)."""
    data = read_bytes(location(path))  # a regular file within the read limit, no FIFO
    if not data.startswith(b"\x89PNG\r\n\x1a\n"):
        raise ValueError(f"{path}: not a PNG file")
    return "data:image/png;base64," + base64.b64encode(data).decode("ascii")
