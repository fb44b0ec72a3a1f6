"""Run configurations: what a ``cmanip run`` or a ``cmanip experiment`` study does, as
one settings value loadable from YAML (``--config FILE``), overridden by the options given
on the command line, and written beside the outputs as ``DIR/config.yaml`` so that
``--config DIR/config.yaml`` replays the run.

Every default is written once: in the settings dataclasses of the layers below
(:class:`~diagrams.herb.settings.EpisodeSettings`,
:class:`~experiments.closedloop_study.ClosedLoopSettings`,
:class:`~experiments.mpf_study.TrialSettings`,
:class:`~experiments.handplan_study.HandplanSettings`,
:class:`~experiments.visuotactile_study.VisuotactileSettings`,
:class:`~experiments.latdespot_study.RelSettings`,
:class:`~planning.hand.solution.HandSolveSettings`), in the study configurations here
(which part, how many trials, which seed) and, for what the closed loop solves, in
:data:`CLOSED_LOOP_SOLVER` here.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

from diagrams.herb.settings import EpisodeSettings
from experiments.closedloop_study import ClosedLoopSettings
from experiments.handplan_study import PARTS as HANDPLAN_PARTS
from experiments.handplan_study import HandplanSettings
from experiments.latdespot_scenes import SceneSettings
from experiments.latdespot_study import PARTS as LATDESPOT_PARTS
from experiments.latdespot_study import RelSettings
from experiments.mpf_study import PARTS as MPF_PARTS
from experiments.mpf_study import TrialSettings
from experiments.visuotactile_study import PARTS as VISUOTACTILE_PARTS
from experiments.visuotactile_study import VisuotactileSettings
from models.config import Fields
from models.settings import settings_from_fields, write_settings
from planning.hand.solution import HandSolveSettings

CLOSED_LOOP_SOLVER = HandSolveSettings(object_name="bottle", solve_seconds=600.0,
                                       solve_trials=400)
"""The closed loop's planning model: the bottle of the thesis' real-robot trials, solved
for 400 search trials (about 60 s; a trial budget makes the policy the same on every
machine), with a 600 s wall-time cap."""

DEFAULT_CACHE = "out/cache"
"""Where solved planning models are kept (relative to the working directory)."""


def _same_object(episode_object: str, solver: HandSolveSettings) -> None:
    if episode_object != solver.object_name:
        raise ValueError(f"the episode pushes {episode_object!r} but the planning model is "
                         f"solved for {solver.object_name!r}; set both (--object sets both)")


@dataclass(frozen=True)
class RunConfig:
    """One closed-loop episode (``cmanip run``).

    Attributes:
        episode: the episode.
        solver: the planning model and its solve (its object must be the episode's).
        cache_dir: where solved planning models are kept.
    """

    episode: EpisodeSettings = EpisodeSettings()
    solver: HandSolveSettings = CLOSED_LOOP_SOLVER
    cache_dir: str = DEFAULT_CACHE

    def __post_init__(self):
        _same_object(self.episode.object_name, self.solver)


@dataclass(frozen=True)
class ClosedLoopStudyConfig:
    """The closed-loop study (``cmanip experiment closedloop``).

    Attributes:
        study: the study.
        solver: the planning model and its solve (its object must be the episodes').
        cache_dir: where solved planning models are kept.
    """

    study: ClosedLoopSettings = ClosedLoopSettings()
    solver: HandSolveSettings = CLOSED_LOOP_SOLVER
    cache_dir: str = DEFAULT_CACHE

    def __post_init__(self):
        _same_object(self.study.episode.object_name, self.solver)


def _check_part(part: str, parts: tuple[str, ...]) -> None:
    if part not in parts:
        raise ValueError(f"part must be one of {', '.join(parts)}, got {part!r}")


@dataclass(frozen=True)
class MpfStudyConfig:
    """The MPF study (``cmanip experiment mpf``; thesis sec. 4.3).

    Attributes:
        part: which figure (``all``: every part into its own folder).
        trials: trials per condition (>= 2).
        seed: study seed; trial j is seeded from (seed, j).
        trial: what one trial does (object, sensors, belief, filters).
    """

    part: str = "compare"
    trials: int = 100
    seed: int = 0
    trial: TrialSettings = TrialSettings()

    def __post_init__(self):
        _check_part(self.part, (*MPF_PARTS, "all"))
        if self.trials < 2:
            raise ValueError(f"trials must be >= 2, got {self.trials}")


@dataclass(frozen=True)
class HandplanStudyConfig:
    """The hand-relative planning study (``cmanip experiment handplan``; thesis ch. 6).

    Attributes:
        part: which comparison.
        study: the study's settings (trials, seed, solver budgets, the problem).
    """

    part: str = "post-contact"
    study: HandplanSettings = HandplanSettings()

    def __post_init__(self):
        _check_part(self.part, HANDPLAN_PARTS)


@dataclass(frozen=True)
class VisuotactileStudyConfig:
    """The visuo-tactile study (``cmanip experiment visuotactile``; Yu and Rodriguez 2018).

    Attributes:
        part: which comparison (``all``: every one).
        study: the study's settings (trials, seed, rig).
    """

    part: str = "methods"
    study: VisuotactileSettings = VisuotactileSettings()

    def __post_init__(self):
        _check_part(self.part, (*VISUOTACTILE_PARTS, "all"))


@dataclass(frozen=True)
class LatDespotStudyConfig:
    """The ch. 7 study (``cmanip experiment latdespot``).

    Attributes:
        part: which experiment: ``rel`` (the hand-relative problem, Fig. 7.3), ``scenes``
            (the Lat-POMDP scenes, Fig. 7.4), ``bound`` (sec. 7.3.5) or ``all``.
        rel: the problem, belief, budgets, trials, horizon and seed of every part.
        scenes: the scenes' settings (parts ``scenes``, ``bound``).
    """

    part: str = "rel"
    rel: RelSettings = RelSettings()
    scenes: SceneSettings = SceneSettings()

    def __post_init__(self):
        _check_part(self.part, LATDESPOT_PARTS)


def load_config(cls, path: Path | None):
    """``cls`` from the YAML file ``path``, or ``cls()`` without one.

    Raises:
        ConfigError: the file is missing or malformed (the message names the field).
    """
    return cls() if path is None else settings_from_fields(cls, Fields.from_file(path))


def with_object(solver: HandSolveSettings, name: str) -> HandSolveSettings:
    """``solver`` for another pushed object."""
    return replace(solver, object_name=name)


def overridden(settings, args, names: dict[str, str]):
    """``settings`` with the fields ``names`` maps options to replaced by the options given
    on the command line (those declared with :func:`cmanip.options.setting_option`, absent
    from ``args`` unless given)."""
    given = vars(args)
    return replace(settings, **{field: given[option] for option, field in names.items()
                                if option in given})


def write_config(config, out_dir: Path) -> Path:
    """Write ``config`` as ``out_dir/config.yaml``; return its path."""
    out_dir.mkdir(parents=True, exist_ok=True)
    path = out_dir / "config.yaml"
    write_settings(config, path, comment="the resolved configuration of this run; replay it "
                                         "with --config")
    return path
