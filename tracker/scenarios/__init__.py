"""End-to-end scenarios that run the whole chain in simulation and score it (e.g. a meeting)."""
