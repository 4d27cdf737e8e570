"""Hardware behind small Protocols: the motor driver and its simulated rig."""
