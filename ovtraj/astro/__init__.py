"""Astrodynamics core: constants, time, frames, elements, atmosphere, propagation."""
