"""Drake LeafSystems and Diagrams, and the Meshcat drawing of beliefs.

The only package that defines ``pydrake.systems`` classes; every system is a thin
adapter over a pure-Python core in ``models``/``estimation``/``planning``.
"""
