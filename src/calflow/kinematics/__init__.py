"""Forward and inverse kinematics of the robots calflow calibrates."""
