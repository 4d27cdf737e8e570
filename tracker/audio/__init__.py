"""Audio: array geometry, localizers, speech activity, talker tracking, sources and room simulation."""
