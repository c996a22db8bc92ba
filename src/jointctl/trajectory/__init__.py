"""Joint trajectories: messages, validation, interpolation, timing and the executor."""
