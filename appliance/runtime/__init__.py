"""Threads and time: ring buffers, sensor sync, supervisor, health, outputs, sd_notify."""
