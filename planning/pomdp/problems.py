"""Generative problems by name, as ``--problem`` gives them: ``tag``,
``rocksample:N:K`` (RockSample(N, K); the reference's layouts for (7, 8) and (11, 11), a
seeded one otherwise) or the path of a Cassandra ``.pomdp`` file (wrapped by
:class:`~planning.pomdp.generative.TabularGenerative`)."""

from __future__ import annotations

from pathlib import Path

from planning.pomdp.generative import GenerativePOMDP, TabularGenerative

PROBLEM_FORMS = "tag, rocksample:N:K (e.g. rocksample:7:8) or a path to a .pomdp file"


def load_problem(name: str) -> GenerativePOMDP:
    """The generative model ``name`` names (see the module docstring).

    Raises:
        ValueError: an unknown name or malformed ``rocksample`` numbers (saying what is
            allowed); :class:`~planning.pomdp.cassandra.PomdpFormatError` (a ValueError)
            for a malformed file, OSError for a missing one.
    """
    if name == "tag":
        from planning.pomdp.tag import Tag

        return Tag()
    if name.startswith("rocksample"):
        from planning.pomdp.rocksample import RockSample

        parts = name.split(":")
        if len(parts) != 3 or not all(p.isdigit() for p in parts[1:]):
            raise ValueError(f"problem {name!r}: expected rocksample:N:K with integers N "
                             f"and K, e.g. rocksample:7:8")
        return RockSample(int(parts[1]), int(parts[2]))
    if name.endswith(".pomdp"):
        from planning.pomdp.cassandra import read_pomdp

        path = Path(name)
        if not path.is_file():
            raise FileNotFoundError(f"{path}: no such .pomdp file")
        return TabularGenerative(read_pomdp(path))
    raise ValueError(f"unknown problem {name!r}: expected {PROBLEM_FORMS}")
