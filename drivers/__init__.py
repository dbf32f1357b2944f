"""Devices behind small interfaces (GRBL laser and plotter over serial, camera, projector display), each with a
simulated twin that speaks the same protocol. ``drivers`` imports nothing from ``design``."""
