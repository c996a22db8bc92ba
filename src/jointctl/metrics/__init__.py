"""Figures of merit read off recorded signals (step and sinusoid responses) and the theory to compare them with."""
