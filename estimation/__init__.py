"""Beliefs and filters over object and robot state (particle filters, smoothing).

Imports ``models``; never ``planning`` or ``diagrams``.
"""
