"""3DAT engine: pan/tilt physics, simulation, control, audio localization and the model workbench.

This package never imports a web framework; ``app/`` serves it.
"""

__version__ = "0.1.0"
