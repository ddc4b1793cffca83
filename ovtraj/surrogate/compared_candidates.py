"""Which candidates a fit compares: the configured ones, more past many samples, or an
earlier fit's choice or shortlist.

``fit_surrogates``' ``candidates`` (an earlier fit's ``selected``, or :func:`shortlist` of
its validation table) restricts a model to those candidates; without them, or when none
of them can be fitted on the new data, every configured candidate is compared.
"""

from __future__ import annotations

from collections.abc import Sequence

import pandas as pd

from ovtraj.config.mission import SurrogateSettings

__all__ = ["configured_classifiers", "configured_regressors", "shortlist", "shortlisted"]


def configured_regressors(n: int, settings: SurrogateSettings) -> list[str]:
    """The regressor candidates of an output with ``n`` training samples: the configured
    ones, and ``large_samples.extra_regressors`` past ``exact_max_samples``."""
    listed = list(settings.regressors)
    large = settings.large_samples
    if large is not None and n > large.exact_max_samples:
        listed += large.extra_regressors
    return list(dict.fromkeys(listed))


def configured_classifiers(settings: SurrogateSettings) -> list[str]:
    """The configured classifier candidates, each once, in config order."""
    return list(dict.fromkeys(settings.classifiers))


def shortlist(validation: pd.DataFrame, size: int) -> dict[str, str | list[str]]:
    """From a fit's validation table: each regressed output's ``size`` candidates of lowest
    CV RMSE (the selection's own criterion, :func:`~ovtraj.surrogate.validation.select_regressor`),
    and the selected classifier: the ``candidates`` of a later fit that compares only these."""
    kept: dict[str, str | list[str]] = {}
    regressors = validation[(validation["kind"] == "regressor") & validation["cv_rmse"].notna()]
    for model, rows in regressors.groupby("model", sort=True):
        ranked = rows.sort_values("cv_rmse", kind="stable")["candidate"].tolist()
        kept[str(model)] = ranked[:size]
    chosen = validation["selected"].astype(bool)
    classifiers = validation[(validation["kind"] == "classifier") & chosen]
    for row in classifiers.itertuples(index=False):
        kept[str(row.model)] = str(row.candidate)  # the last set's (the main model's)
    return kept


def shortlisted(kept: str | Sequence[str] | None, configured: list[str]) -> list[str]:
    """The configured candidates among ``kept`` (one name or several), in config order; all
    of them when none is kept."""
    listed = [kept] if isinstance(kept, str) else list(kept or ())
    return [c for c in configured if c in listed] or configured
