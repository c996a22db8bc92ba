"""Seeing a run: videos drawn after it and MuJoCo's live viewer during it."""
