"""Monocular collision warning appliance (Woelk, Gehrig, Koch: "A Monocular Collision Warning System")."""

__version__ = "0.1.0"
