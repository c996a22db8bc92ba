"""Identify a joint, measure its closed-loop frequency response, compute gains: tuning without a ruler."""
