"""Scoring a run against a simulated recording's truth (``collision-warning evaluate``)."""
