"""Controllers of one axis: design with python-control, the compiled loop, shaping and limits."""
