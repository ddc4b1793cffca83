"""Thin Prefect tasks around library calls."""
