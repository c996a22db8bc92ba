"""Tools around the control loop: safe command expressions and command signal sources."""
