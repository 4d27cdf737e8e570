"""Refit a model: starting values by search and least squares, then the nonlinear fit."""
