"""Models I–V of the XYΘ micro-robot: kinematics, the pose-difference cost and identification."""
