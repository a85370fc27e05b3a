"""The robot's brain: geometry, EKF, fuzzy control, collision avoidance, formations."""
