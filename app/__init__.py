"""The 3DAT console service: FastAPI app, settings, keys, storage, telemetry and the 3D view."""
