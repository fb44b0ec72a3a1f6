"""Geometric tolerances of the planar world, shared by the readable numpy reference
(:mod:`models.planar.polygon`, :mod:`models.planar.pushing`) and its compiled kernels
(:mod:`models.planar.kernels`), so both resolve contacts with the same numbers."""

CONTACT_POINT_TOLERANCE_M = 5e-4
"""Vertices within this depth (m) of the deepest one share the contact (face contacts)."""

OVERLAP_TOLERANCE_M = 1e-6
"""Overlaps shallower than this (m) are left alone (far below every other length here)."""
