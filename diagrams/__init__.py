"""Drake LeafSystems and Diagrams, Meshcat drawing, and the ``cmanip`` command line.

The only package that defines ``pydrake.systems`` classes; every system is a thin
adapter over a pure-Python core in ``models``/``estimation``/``planning``.
"""
