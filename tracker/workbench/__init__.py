"""The model workbench: compare the model with measurements, diagnose missing effects, refit."""
