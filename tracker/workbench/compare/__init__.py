"""Compare a model with a measurement: k-step prediction, error by regime, residual tests."""
