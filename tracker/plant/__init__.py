"""The axis physics: parameters, the catalogue of physical effects, the model and its simulator."""
