"""The robots' bodies and senses: kinematics, cameras, and the world process."""
