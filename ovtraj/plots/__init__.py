"""Plots of the optimisation and the mission (matplotlib, Agg canvas)."""
