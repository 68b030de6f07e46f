"""Shipped configuration files (installed as the package ``appliance.resources``)."""
