"""Hexapod geometry, kinematics, the model ladder, loop closure, identification, calibration."""
