"""``cmanip scenes``: the built-in data files a user can name instead of a path."""

from __future__ import annotations

from cmanip.options import subcommand
from models.config import builtin_names

KINDS = ("scenes", "objects", "tactile", "planar_sensors", "arms")


def register(commands) -> None:
    scenes = subcommand(commands, "scenes", "list the built-in scenes, objects, tactile "
                                            "layouts and planar sensor layouts")
    scenes.set_defaults(handler=_scenes)


def _scenes(args) -> int:
    for kind in KINDS:
        print(f"{kind}: {', '.join(builtin_names(kind))}")
    return 0
