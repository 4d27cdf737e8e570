"""Measurements: the CSV log, the EMPS benchmark, state estimation and inverse dynamics."""
