"""Figures and their PNG bytes: matplotlib's Agg canvas, no pyplot, reproducible files.

A plot's PNG is part of stored products whose files are listed with their SHA-256
(a front's ``meta.json``, a plan's ``files.json``), and the same config and seed must
give byte-identical files. Agg's PNG writer adds no timestamp; the only varying text
chunk is matplotlib's default ``Software`` entry (its version), removed here, so a file
depends only on what is drawn (and on the fonts and the Agg renderer).
"""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

from ovtraj.store.backends import location
from ovtraj.store.files import write_bytes

__all__ = ["DPI", "figure", "png_bytes", "write_png"]

DPI = 100
PNG_METADATA: dict[str, str | None] = {"Software": None}  # no matplotlib version in the file


def figure(size: tuple[float, float]) -> Any:
    """A new Figure of ``size`` inches (constrained layout) on its own Agg canvas."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure  # no pyplot: no global state, safe in workers

    fig = Figure(figsize=size, constrained_layout=True)
    FigureCanvasAgg(fig)
    return fig


def png_bytes(fig: Any) -> bytes:
    """The figure as PNG bytes (``DPI``, no ``Software`` text chunk)."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=DPI, metadata=PNG_METADATA)
    return buffer.getvalue()


def write_png(fig: Any, path: Path | str) -> Path:
    """Write the figure as PNG to ``path`` (temporary name, then rename); returns the path."""
    path = location(path)
    write_bytes(path, png_bytes(fig), replace=True)
    return path
