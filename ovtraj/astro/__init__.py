"""Astrodynamics core: angles, constants, time, frames, elements, atmosphere, propagation."""
