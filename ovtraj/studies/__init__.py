"""The seed studies: each reproduces a published method and its figures, apart from the
mission chain (which never imports them; the layer contracts in pyproject.toml say so).

- :mod:`.optimal_entry`: seed 001, the Gauss pseudospectral maximum-range entry
  (``ovtraj optimal-entry``, docs/optimal_entry.md);
- :mod:`.maneuver`: seed 003, the upper stage's impulsive and finite-burn manoeuvre
  (``ovtraj maneuver``, docs/maneuver.md);
- :mod:`.deorbit_burn`: seed 004, the finite-thrust deorbit burn by iteration of the
  ignition point (``ovtraj deorbit-burn``, docs/deorbit_burn.md).

They share the numeric kernels of :mod:`ovtraj.astro`, the configuration models of
:mod:`ovtraj.config` and the store layer, nothing else.
"""
