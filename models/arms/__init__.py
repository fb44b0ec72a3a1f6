"""Manipulators in known static worlds for configuration estimation (thesis ch. 5): arm
files, their Drake plants, batched kinematics and the environment's signed distance."""
