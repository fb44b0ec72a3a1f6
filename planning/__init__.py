"""Planners that act under uncertainty (POMDP models, QMDP, point-based solvers, DESPOT).

Imports ``models`` and ``estimation``; never ``diagrams``.
"""
