"""Surrogate models of the whole-mission chain (SPEC step 5, issue 7).

SMT regressors per output and a scikit-learn feasibility classifier, each chosen by
k-fold cross-validation and judged on a held-out set; see ``docs/surrogate.md``.
"""

from ovtraj.surrogate.scaling import SurrogateError, UnitCube
from ovtraj.surrogate.surrogate_set import SurrogateSet, fit_surrogates, training_data_hash

__all__ = ["SurrogateError", "SurrogateSet", "UnitCube", "fit_surrogates", "training_data_hash"]
