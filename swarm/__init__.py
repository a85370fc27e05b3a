"""Distributed leader-follower formation emulator (vision, fuzzy control, EKF)."""

__version__ = "0.1.0"
