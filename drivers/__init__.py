"""Device drivers: camera, pan-tilt unit, vehicle CAN, HMI CAN.

They import nothing from ``appliance/``.
"""
