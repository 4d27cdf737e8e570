"""Experiments: closed-loop runs on the twin and the seed's friction-identification sweep."""
