"""Shared fixtures: built-in scenes and the (expensive) kinematic model, built once; a small
lattice (2 cm, 5 x 5 points) in a scene with a wall along the hand's right, and the small
ch. 7 problem on it."""

from dataclasses import replace

import numpy as np
import pytest

from models.config import ConfigError
from models.herb.kinematics import PlanarHandIK
from models.herb.scene import Obstacle, PlanarPose, SceneSpec
from models.objects import ObjectSpec
from planning.lattice.grid import LatticeSpec
from planning.lattice.ik_table import load_ik_table


@pytest.fixture
def refused(tmp_path):
    """``refused(load, text, match)``: write ``text`` to a file, check that ``load(path)``
    raises a :class:`ConfigError` naming the file and matching ``match``; return it."""
    def check(load, text: str, match: str) -> ConfigError:
        path = tmp_path / "input.yaml"
        path.write_text(text)
        with pytest.raises(ConfigError, match=match) as err:
            load(path)
        assert str(path) in str(err.value)
        return err.value
    return check


@pytest.fixture(scope="session")
def empty_scene() -> SceneSpec:
    return SceneSpec.load("empty")


@pytest.fixture(scope="session")
def empty_ik(empty_scene) -> PlanarHandIK:
    return PlanarHandIK(empty_scene)


@pytest.fixture(scope="session")
def box_world():
    """The planar world with the thesis' box and the medium sensor layout."""
    from models.planar.world import PlanarWorld

    return PlanarWorld.load("box", "medium")


@pytest.fixture(scope="session")
def box_manifold(box_world):
    """The analytic contact manifold of the box (3 deg, 1 mm: a little coarser than the
    thesis' 1.15 deg to keep the suite quick)."""
    import numpy as np

    from estimation.hand.manifolds import AnalyticManifold

    return AnalyticManifold(box_world, dtheta_rad=np.deg2rad(3.0))


@pytest.fixture(scope="session")
def small_hand_model():
    """A small hand-relative planning POMDP: the ch. 6 box, fingertip sensors, a 22 cm x
    16 cm trust region and 4 Monte Carlo samples per state (a few seconds to build)."""
    import numpy as np

    from models.planar.world import PlanarWorld
    from planning.hand.discretization import HandProblemSpec
    from planning.hand.model import build_hand_pomdp

    world = PlanarWorld.load("small_box", "fingertips")
    spec = HandProblemSpec(trust_x_m=(0.0, 0.22), trust_y_m=(-0.08, 0.08),
                           samples_per_state=4)
    return build_hand_pomdp(world, spec, rng=np.random.default_rng(0), progress=False)


@pytest.fixture(scope="session")
def small_hand_solution(tmp_path_factory):
    """A small solved hand problem (as ``small_hand_model``, 2 samples per state; the
    point-based solver stopped after a few trials), cached in a temporary directory."""
    from planning.hand.discretization import HandProblemSpec
    from planning.hand.solution import HandSolveSettings, solve_hand_problem

    spec = HandProblemSpec(trust_x_m=(0.0, 0.22), trust_y_m=(-0.08, 0.08),
                           samples_per_state=2)
    settings = HandSolveSettings(spec=spec, solve_seconds=5.0, solve_trials=3, belief_count=3,
                                 belief_particles=200)
    cache = tmp_path_factory.mktemp("hand_cache")
    return solve_hand_problem(settings, cache_dir=cache, progress=False), settings, cache


def _synthetic_push_log(seed: int = 0, c_m: float = 0.03):
    """A pusher log without Drake: rect1 pushed straight by both rods (1-3 s), then turned
    by one rod under the ellipsoidal limit surface with sticking contact (4-6 s), with the
    rig's kind of noise: forces 0.05 N, rods 0.2 mm, camera at 100/3 Hz with a (5, -3) mm,
    1 deg bias, 3 mm and 1.5 deg noise, hidden during 2-2.5 s. Rows at 100 Hz."""
    import numpy as np

    from models.pusher.log import PushLog

    rng = np.random.default_rng(seed)
    dt, radius, half = 0.01, 0.003125, 0.045
    pose = np.zeros(3)
    rows = []
    for k in range(int(7.0 / dt)):
        t = k * dt
        c, s = np.cos(pose[2]), np.sin(pose[2])
        R = np.array([[c, -s], [s, c]])
        forces = np.zeros((2, 2))
        if t < 1.0:  # approach: rods behind the back face, not touching yet
            rods = np.array([[-half - radius - 0.03 * (1 - t), 0.02],
                             [-half - radius - 0.03 * (1 - t), -0.02]])
            rods = rods @ R.T + pose[:2]
            twist = np.zeros(3)
        elif t < 3.0:  # straight two-rod push at 60 mm/s
            twist = np.array([0.06, 0.0, 0.0])
            points = np.array([[-half, 0.02], [-half, -0.02]])
            forces = np.array([[1.0, 0.0], [1.0, 0.0]]) @ R.T
            rods = (points - radius * np.array([1.0, 0.0])) @ R.T + pose[:2]
        elif t < 4.0:  # the rods wait, apart from the object
            twist = np.zeros(3)
            rods = np.array([[-half - 0.05, 0.02], [-half - 0.05, -0.02]]) @ R.T + pose[:2]
        elif t < 6.0:  # one rod, 25 mm off-centre, sticking (reference, sticking case)
            xc, yc = -half, 0.025
            vp = np.array([0.04, 0.0])
            D = c_m**2 + xc**2 + yc**2
            vx = ((c_m**2 + xc**2) * vp[0] + xc * yc * vp[1]) / D
            vy = (xc * yc * vp[0] + (c_m**2 + yc**2) * vp[1]) / D
            w = (xc * vy - yc * vx) / c_m**2
            twist = np.array([vx, vy, w])
            f_obj = 1.5 * np.array([vx, vy]) / np.hypot(vx, vy)
            forces[0] = R @ f_obj
            rods = np.array([R @ (np.array([xc, yc]) - radius * f_obj / 1.5) + pose[:2],
                             R @ np.array([xc, yc - 0.1]) + pose[:2]])
        else:
            twist = np.zeros(3)
            rods = np.array([[-half - 0.05, 0.0], [-half - 0.05, -0.1]]) @ R.T + pose[:2]
        vision_ok = (k % 3 == 0) and not (2.0 <= t < 2.5)
        vision = (pose + np.array([0.005, -0.003, np.deg2rad(1.0)])
                  + rng.normal(0, [0.003, 0.003, np.deg2rad(1.5)])) if vision_ok else np.full(3,
                                                                                      np.nan)
        rows.append((t, rods + rng.normal(0, 0.0002, (2, 2)),
                     forces + rng.normal(0, 0.05, (2, 2)), vision_ok, vision, pose.copy()))
        pose = pose + np.concatenate([R @ twist[:2], [twist[2]]]) * dt
    t, rods, forces, ok, vision, truth = (np.array(v) for v in zip(*rows, strict=True))
    return PushLog(t, rods, forces, ok, vision, truth, np.full((len(t), 3), np.nan), "rect1",
                   radius, 0.3, "synthetic")


@pytest.fixture(scope="session")
def synthetic_push_log():
    """A Drake-free pusher log with ground truth (see :func:`_synthetic_push_log`)."""
    return _synthetic_push_log()


@pytest.fixture(scope="session")
def synthetic_push_factory():
    """Make more synthetic pusher logs: ``factory(seed, c_m)``."""
    return _synthetic_push_log


#: Half the planar hand's width (m): its outline spans y in [-6, 6] cm.
HAND_HALF_WIDTH_M = 0.06

SMALL_PROBLEM = """trust_x_m: [0.0, 0.20]
trust_y_m: [-0.06, 0.06]
free_cell_m: 0.02
contact_states: false
step_m: 0.02
actions:
  forward: [1, 0]
  back: [-1, 0]
  left: [0, 1]
  right: [0, -1]
samples_per_state: 6
"""


def wall_scene() -> SceneSpec:
    """The empty scene, the bottle, and a wall along the hand's right side, 1 cm from the
    planar hand's outline (6 cm from the palm's axis) and ending 10 cm ahead of the palm:
    free at the start, hit by a 2 cm move right, and clear of a bottle ahead of the
    fingertips."""
    scene = SceneSpec.load("empty", object_override="bottle")
    start = scene.hand_start
    wall = ObjectSpec(name="wall", shape="box", height_m=0.2, mass_kg=1.0,
                      material=scene.object.material, rgba=(0.5, 0.5, 0.5, 1.0),
                      size_m=(0.20, 0.04))
    pose = PlanarPose(start.x, start.y - HAND_HALF_WIDTH_M - 0.01 - 0.02, 0.0)
    return replace(scene, obstacles=(Obstacle(wall, pose),))


@pytest.fixture(scope="session")
def wall():
    return wall_scene()


@pytest.fixture(scope="session")
def small_spec(wall) -> LatticeSpec:
    return LatticeSpec(start=tuple(wall.hand_start.as_array()), resolution_m=0.02,
                       x_range_m=(-0.04, 0.04), y_range_m=(-0.04, 0.04))


@pytest.fixture(scope="session")
def small_table(wall, small_spec, tmp_path_factory):
    return load_ik_table(wall, small_spec, cache_dir=tmp_path_factory.mktemp("cache"),
                         progress=False)


@pytest.fixture(scope="session")
def small_problem(tmp_path_factory):
    """The path of a small ch. 7 problem: 2 cm cells and moves, 20 cm x 12 cm."""
    path = tmp_path_factory.mktemp("problem") / "small.yaml"
    path.write_text(SMALL_PROBLEM)
    return path


@pytest.fixture(scope="session")
def moves() -> np.ndarray:
    """forward, back, left, right by 2 cm (hand frame)."""
    return np.array([[0.02, 0, 0], [-0.02, 0, 0], [0, 0.02, 0], [0, -0.02, 0]])
