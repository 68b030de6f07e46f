"""Batch replay of many recordings on Ray (``collision-warning batch``)."""
