"""Diagnose the missing effect: screen the catalogue, judge candidates by simulation, explain."""
