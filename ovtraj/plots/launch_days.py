"""Marks shared by the plots over launch days (the window's and its porkchop)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

__all__ = ["mark_days_without_plan"]


def mark_days_without_plan(ax: Any, days: Sequence[Any]) -> None:
    """A grey cross on the x axis of ``ax`` at each of ``days`` (the launch days that have
    no plan, in the axis's own x values), labelled "no plan"."""
    ax.plot(
        days,
        [0.0] * len(days),
        linestyle="none",
        marker="x",
        color="0.5",
        transform=ax.get_xaxis_transform(),  # y in axes fraction: on the axis
        clip_on=False,
        label="no plan",
    )
