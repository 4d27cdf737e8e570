"""Independent truth generator and blind matrix for the model workbench (imports nothing from tracker)."""
