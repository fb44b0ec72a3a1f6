"""A Meshcat server for this project: bound to the loopback interface only.

Drake's default listens on every interface (``*``), which would publish a run's scene to
the network; every command here serves on ``localhost``, and the recording
(``StaticHtml``) is what leaves the machine.
"""

from __future__ import annotations

from pydrake.geometry import Meshcat, MeshcatParams


def local_meshcat() -> Meshcat:
    """A Meshcat listening on localhost (the first free port from 7000)."""
    params = MeshcatParams()
    params.host = "localhost"
    return Meshcat(params)
