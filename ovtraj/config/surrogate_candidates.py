"""The names of the surrogate candidates, as the config accepts them.

The candidates themselves (what builds each one, its options, what the fit and the store
need to know of it) are declared in :mod:`ovtraj.surrogate.candidates`. The config layer
sits below ``ovtraj.surrogate`` (pyproject.toml's import contracts), so it cannot read
that registry; it validates ``mission.surrogate`` against these names when a scenario is
loaded, before a DoE is spent on a name no fit could use. The registry declares exactly
these candidates, in this order (``tests/test_surrogate.py``).
"""

from __future__ import annotations

from typing import Literal, get_args

__all__ = ["CLASSIFIER_NAMES", "REGRESSOR_NAMES", "ClassifierName", "RegressorName"]

RegressorName = Literal["KRG", "KPLS", "RBF", "QP", "ET", "GBT"]
ClassifierName = Literal["svc", "gpc", "logistic"]
REGRESSOR_NAMES: tuple[str, ...] = get_args(RegressorName)
CLASSIFIER_NAMES: tuple[str, ...] = get_args(ClassifierName)
