"""The configuration lattice over HERB's arm, Lat-POMDP and Lat-DESPOT (thesis ch. 7)."""
