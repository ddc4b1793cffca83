"""The surrogate set of the whole-mission chain: the selected model of every output and of
feasibility, on the design space's unit cube, with their validation.

:func:`~ovtraj.surrogate.fitting.fit_surrogates` makes one from a design of experiments;
:meth:`SurrogateSet.save` and :meth:`SurrogateSet.load` keep it in a store as data
(:mod:`ovtraj.surrogate.set_store`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ovtraj.config.mission import SurrogateSettings
from ovtraj.store.files import Digest
from ovtraj.surrogate.fitted_models import FeasibilityClassifier, Regressor
from ovtraj.surrogate.scaling import SurrogateError, UnitCube
from ovtraj.surrogate.set_store import read_set, write_set

__all__ = ["SurrogateSet"]


class SurrogateSet:
    """Selected surrogates of every output and of feasibility, with their validation.

    Attributes: ``input_names``, ``output_names``, ``cube`` (the design space's
    :class:`UnitCube`), ``selected`` (output name -> candidate; ``"feasible"`` ->
    classifier or ``"all-feasible"``), ``validation`` and ``predictions`` (tables, see
    ``docs/surrogate.md``), ``data_hash``
    (:func:`~ovtraj.surrogate.training_data.training_data_hash`), ``settings``, and
    ``meta`` (the contents of ``meta.json`` for a loaded set; empty after a fit).
    """

    def __init__(
        self,
        *,
        input_names: tuple[str, ...],
        output_names: tuple[str, ...],
        cube: UnitCube,
        regressors: dict[str, Regressor],
        classifier: FeasibilityClassifier,
        selected: dict[str, str],
        validation: pd.DataFrame,
        predictions: pd.DataFrame,
        data_hash: str,
        settings: SurrogateSettings,
        meta: dict[str, Any] | None = None,
    ) -> None:
        self.input_names = tuple(input_names)
        self.output_names = tuple(output_names)
        self.cube = cube
        self._regressors = dict(regressors)
        self._classifier = classifier
        self.selected = dict(selected)
        self.validation = validation
        self.predictions = predictions
        self.data_hash = data_hash
        self.settings = settings
        self.meta = dict(meta or {})

    def __repr__(self) -> str:
        return (
            f"SurrogateSet(inputs={self.input_names}, selected={self.selected}, "
            f"data_hash={self.data_hash!r})"
        )

    def regressor(self, output: str) -> Regressor:
        """The selected model of ``output``."""
        return self._regressors[output]

    @property
    def classifier(self) -> FeasibilityClassifier:
        """The selected feasibility classifier (or the constant one)."""
        return self._classifier

    @property
    def output_inputs(self) -> dict[str, tuple[str, ...]]:
        """The outputs fitted on some of the inputs only -> those inputs' names."""
        return {
            name: tuple(self.input_names[k] for k in regressor.columns)
            for name, regressor in self._regressors.items()
            if regressor.columns is not None
        }

    def _unit(self, X: np.ndarray) -> np.ndarray:
        try:
            x = np.asarray(X, dtype=float)
        except (TypeError, ValueError) as err:
            raise SurrogateError(f"X: not a numeric array ({err})") from None
        if x.ndim != 2 or x.shape[1] != self.cube.dim:
            raise SurrogateError(
                f"X: expected shape (m, {self.cube.dim}) for inputs {self.input_names}, "
                f"got {x.shape}"
            )
        if not np.all(np.isfinite(x)):
            raise SurrogateError("X: NaN or infinite values; every input must be finite")
        return self.cube.to_unit(x)

    def predict(self, X: np.ndarray) -> dict[str, np.ndarray]:
        """Physical inputs (m, d) -> {output name: prediction (m,)} of the selected models."""
        u = self._unit(X)
        if u.shape[0] == 0:
            return {name: np.empty(0) for name in self.output_names}
        return {name: self._regressors[name].predict(u) for name in self.output_names}

    def feasibility(self, X: np.ndarray) -> np.ndarray:
        """Physical inputs (m, d) -> probability of feasibility (m,) in [0, 1]."""
        u = self._unit(X)
        return self._classifier.proba(u) if u.shape[0] else np.empty(0)

    def save(
        self,
        directory: Path,
        *,
        meta: dict[str, Any],
        views: dict[str, Digest] | None = None,
    ) -> dict[str, Digest]:
        """Write the set to ``directory`` (:mod:`ovtraj.surrogate.set_store`), ``meta.json``
        last.

        ``meta`` (e.g. the run id) is merged into ``meta.json``; its keys must not collide
        with the set's own keys and its values must be JSON-serialisable. ``views`` are
        files already written there (plots) to list in ``meta.json`` too. Returns the
        digest of every file written, ``meta.json`` included. A stored set is never
        overwritten: saving other content over it raises :class:`~ovtraj.store.files.StoreError`.
        """
        return write_set(self, directory, meta, views)

    @classmethod
    def load(cls, directory: Path, expected: Digest | None = None) -> SurrogateSet:
        """Read a set written by :meth:`save`; SurrogateError names a missing or changed file.

        ``expected`` is the digest of ``meta.json`` when a parent product lists it.
        """
        return cls(**read_set(directory, expected))
