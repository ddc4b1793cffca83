"""Surrogate models of the whole-mission chain (SPEC step 5).

SMT regressors per output and a scikit-learn feasibility classifier, each chosen by
k-fold cross-validation and judged on a held-out set; see ``docs/surrogate.md``.
Importing the package changes nothing in SMT or scikit-learn: SMT's speed-ups are
installed by the Kriging models when one is built (:mod:`ovtraj.surrogate.estimators`).
"""

from ovtraj.surrogate.fitting import fit_surrogates
from ovtraj.surrogate.scaling import SurrogateError, UnitCube
from ovtraj.surrogate.surrogate_set import SurrogateSet
from ovtraj.surrogate.training_data import training_data_hash

__all__ = ["SurrogateError", "SurrogateSet", "UnitCube", "fit_surrogates", "training_data_hash"]
