"""HERB (thesis sec. 3.5, 7.1): the mount, the BarrettHand, scenes on a table, tactile patches,
kinematics and inverse kinematics, and the 3-D world that puts them in one plant."""
