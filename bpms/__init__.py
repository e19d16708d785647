"""BPMS Suite: software for the Body Pose Measurement System inertial motion-capture garment."""

__version__ = "0.2.0"
