"""The world: robot, hand, objects, scenes, contact parameters and sensor definitions.

No planning and no estimation lives here. Everything is built from data files in
``models/assets/`` (or files a user passes by path).
"""
