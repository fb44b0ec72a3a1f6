"""Planner budgets under load and memory over long runs (part of ``cmanip bench
robustness``).

**Budgets.** DESPOT on Tag and Lat-DESPOT on the ``cul_de_sac`` scene's Lat-POMDP (the
ch. 7 problem, discrete model, Rel-QMDP and Lift-QMDP bounds), each with a wall-clock
budget per decision and no trial cap, plan ``decisions`` times from beliefs drawn from
their initial belief: once on an idle machine and once while a busy process saturates
another core. A decision's overrun is its whole ``plan`` call's wall time beyond the
budget (ms; the tree's set-up and the answer's assembly included, not only the search
loop DESPOT times itself). The bar of the issue: the p99 overrun within 10 % of the budget
plus the decision's longest trial (a search can only stop between trials).

**Memory.** Resident memory (RSS) sampled every ``sample_every`` steps of two long runs:
``decisions`` closed-loop decisions on the planar model (Rel-DESPOT on the continuous
hand-relative model, the MPF tracking the object; the Drake diagram takes about a second
per decision, too slow for thousands) and ``smoother_updates`` updates of the visuo-tactile
smoother (a simulated push replayed end to end until the count is reached: the object
jumps back at each replay, which the camera cost's Huber kernel absorbs). The growth is
the least-squares slope of RSS against steps after the first fifth (warm-up: compiled
kernels, caches), in MB per 1000 steps; open file descriptors are counted before and
after.

**Meshcat sessions.** ``sessions`` Meshcat servers one after another, as runs with
``--meshcat`` or a notebook make them: each opens on localhost, takes a browser-like
client (a WebSocket handshake over a plain socket: Drake counts it in
``GetNumActiveConnections``), draws and records, writes its ``StaticHtml``, loses the
client and is dropped. Counted: connections still open after their client left, and the
process' threads, file descriptors and listening TCP sockets before and after (before:
after one warm-up session, whose one-time costs are not a leak).
"""

from __future__ import annotations

import base64
import gc
import multiprocessing
import os
import socket
import time
from functools import partial
from pathlib import Path

import numpy as np
import psutil
from tqdm import tqdm

from experiments.latdespot_continuous import EpisodeRunner
from experiments.latdespot_study import RelSettings, build_rel_problem

BUDGET_TOLERANCE = 0.10
"""The p99 overrun may exceed the budget by this fraction plus the longest trial."""


def _spin(stop) -> None:  # pragma: no cover (a child process)
    """Keep one core busy until ``stop`` is set."""
    x = 0
    while not stop.is_set():
        for i in range(100_000):
            x += i * i


class BusyCore:
    """A context in which a spawned process keeps one core saturated."""

    def __enter__(self):
        context = multiprocessing.get_context("spawn")
        self._stop = context.Event()
        self._process = context.Process(target=_spin, args=(self._stop,), daemon=True)
        self._process.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._process.join(timeout=5)
        if self._process.is_alive():
            self._process.kill()
        return False


def _decisions(plan, beliefs, desc: str, progress: bool) -> dict:
    """Time ``plan(belief)`` on each belief: (D,) arrays of overruns and longest trials."""
    walls, longest = [], []
    for belief in tqdm(beliefs, desc=desc, disable=not progress, leave=False):
        start = time.perf_counter()
        result = plan(belief)
        walls.append((time.perf_counter() - start) * 1e3)
        longest.append(result.stats["trial_ms_max"])
    return {"wall_ms": np.array(walls), "trial_ms_max": np.array(longest)}


def _budget_report(runs: dict, budget_s: float) -> dict:
    """Overrun statistics (ms) of a planner's idle and loaded runs, and the bar."""
    out = {"budget_ms": budget_s * 1e3}
    for load, run in runs.items():
        overrun = np.maximum(run["wall_ms"] - budget_s * 1e3, 0.0)
        allowed = BUDGET_TOLERANCE * budget_s * 1e3 + float(np.percentile(
            run["trial_ms_max"], 99))
        out[load] = {
            "decisions": int(len(overrun)),
            "overrun_ms_p50": float(np.percentile(overrun, 50)),
            "overrun_ms_p99": float(np.percentile(overrun, 99)),
            "overrun_ms_max": float(overrun.max()),
            "trial_ms_max_p99": float(np.percentile(run["trial_ms_max"], 99)),
            "allowed_p99_ms": allowed,
            "within_budget": bool(np.percentile(overrun, 99) <= allowed),
        }
    return out


def _both_loads(plan, beliefs, name: str, progress: bool) -> dict:
    runs = {"idle": _decisions(plan, beliefs, f"{name} idle", progress)}
    with BusyCore():
        runs["loaded"] = _decisions(plan, beliefs, f"{name} loaded", progress)
    return runs


def despot_budget(decisions: int, budget_s: float, *, seed: int = 0,
                  progress: bool = True) -> dict:
    """DESPOT (K = 500) on Tag, ``decisions`` decisions from the initial belief."""
    from planning.pomdp.despot import DespotSettings
    from planning.pomdp.online import DespotPlanner
    from planning.pomdp.problems import load_problem

    model = load_problem("tag")
    planner = DespotPlanner(model, DespotSettings(seconds=budget_s))
    rng = np.random.default_rng((seed, 41))
    beliefs = [model.sample_initial(1000, rng=rng) for _ in range(decisions)]
    planner.plan(beliefs[0], rng=rng)  # warm-up: compiled kernels
    runs = _both_loads(lambda b: planner.plan(b, rng=rng), beliefs, "DESPOT Tag", progress)
    return _budget_report(runs, budget_s)


def lat_despot_budget(decisions: int, budget_s: float, *, seed: int = 0,
                      cache_dir: Path | None = Path("out/cache"),
                      progress: bool = True) -> dict:
    """Lat-DESPOT on ``cul_de_sac`` (the ch. 7 problem and belief), ``decisions``
    decisions from the lattice's start (its IK table solved into ``cache_dir`` on first
    use)."""
    from experiments.latdespot_scenes import SceneSettings, scene_lat_pomdp
    from planning.lattice.planners import LatDespotPlanner
    from planning.pomdp.despot import DespotSettings

    rel = RelSettings()
    cache = None if cache_dir is None else str(cache_dir)
    pomdp = scene_lat_pomdp("cul_de_sac", rel, SceneSettings(cache_dir=cache),
                            progress=progress)
    model, belief, lattice = pomdp.model, pomdp.initial, pomdp.lattice
    planner = LatDespotPlanner(pomdp, DespotSettings(
        scenarios=rel.despot_scenarios, depth=rel.despot_depth, seconds=budget_s))
    rng = np.random.default_rng((seed, 43))
    start = lattice.start_point
    beliefs = [model.index(belief.sample(model.world, rel.despot_particles, rng=rng))[:, None]
               for _ in range(decisions)]
    planner.plan(beliefs[0], rng=rng, point=start)  # warm-up
    runs = _both_loads(lambda b: planner.plan(b, rng=rng, point=start), beliefs,
                       "Lat-DESPOT cul_de_sac", progress)
    return _budget_report(runs, budget_s)


def _rss_mb() -> float:
    return psutil.Process().memory_info().rss / 2**20


def _open_files() -> int:
    return len(os.listdir("/proc/self/fd")) if os.path.isdir("/proc/self/fd") else \
        psutil.Process().num_fds()


def growth_mb_per_1000(steps: np.ndarray, rss_mb: np.ndarray) -> float:
    """The least-squares slope of RSS (MB) against steps after the first fifth, per 1000
    steps."""
    keep = steps >= steps[-1] / 5
    return float(np.polyfit(steps[keep], rss_mb[keep], 1)[0] * 1000)


MEMORY_SAMPLES = 20
"""RSS samples over a long run at least (fewer only when the run has fewer steps)."""

MIN_MEMORY_STEPS = 10
"""The shortest long run whose growth can be measured: the slope needs samples after the
first fifth."""


def _sample_every(steps: int, sample_every: int | None) -> int:
    if steps < MIN_MEMORY_STEPS:
        raise ValueError(f"a memory run needs at least {MIN_MEMORY_STEPS} steps, got {steps}")
    return sample_every if sample_every is not None else max(1, steps // MEMORY_SAMPLES)


def closed_loop_memory(decisions: int, *, sample_every: int | None = None, seed: int = 0,
                       progress: bool = True) -> dict:
    """RSS over ``decisions`` closed-loop decisions on the planar model (episodes of
    Rel-DESPOT and the MPF, :class:`~experiments.latdespot_continuous.EpisodeRunner`, with
    a 20-trial DESPOT budget so that thousands of decisions take minutes), sampled every
    ``sample_every`` decisions (None: :data:`MEMORY_SAMPLES` times over the run).

    Raises:
        ValueError: fewer than :data:`MIN_MEMORY_STEPS` decisions.
    """
    sample_every = _sample_every(decisions, sample_every)
    settings = RelSettings(seed=seed, continuous_despot_trials=20, horizon=50)
    runner = EpisodeRunner(settings, partial(build_rel_problem, progress=progress))
    files_before = _open_files()
    steps, rss = [], []
    done, episode = 0, 0
    bar = tqdm(total=decisions, desc="closed-loop decisions", disable=not progress,
               leave=False)

    def on_decision() -> None:
        nonlocal done
        done += 1
        bar.update()
        if done % sample_every == 0:
            steps.append(done)
            rss.append(_rss_mb())

    while done < decisions:
        runner.run(episode, on_decision=on_decision)
        episode += 1
    bar.close()
    steps, rss = np.array(steps), np.array(rss)
    return {"decisions": done, "rss_mb_start": float(rss[0]), "rss_mb_end": float(rss[-1]),
            "growth_mb_per_1000": growth_mb_per_1000(steps, rss),
            "open_files_before": files_before, "open_files_after": _open_files()}


def smoother_memory(updates: int, *, sample_every: int | None = None, seed: int = 0,
                    progress: bool = True) -> dict:
    """RSS over ``updates`` smoother updates (the recommended settings) on a simulated
    push replayed end to end, sampled every ``sample_every`` updates (None:
    :data:`MEMORY_SAMPLES` times over the run).

    Raises:
        ValueError: fewer than :data:`MIN_MEMORY_STEPS` updates.
    """
    sample_every = _sample_every(updates, sample_every)
    from estimation.pushing.noise import identify_from_runs
    from estimation.pushing.smoother import VisuoTactileSmoother, recommended_settings
    from experiments.fault_bench import simulated_push

    steps_in, polygon = simulated_push(seed)
    noise, _, _ = identify_from_runs([steps_in], polygon)
    smoother = VisuoTactileSmoother(polygon, noise, recommended_settings(),
                                    rod_radius_m=steps_in.rod_radius_m)
    first, pose = steps_in.start()
    smoother.start(pose)
    files_before = _open_files()
    steps, rss = [], []
    for n in tqdm(range(1, updates + 1), desc="smoother updates", disable=not progress,
                  leave=False):
        k = first + (n % (len(steps_in) - first))
        smoother.step(*steps_in.inputs(k), steps_in.vision_at(k))
        if n % sample_every == 0:
            steps.append(n)
            rss.append(_rss_mb())
    steps, rss = np.array(steps), np.array(rss)
    return {"updates": updates, "rss_mb_start": float(rss[0]), "rss_mb_end": float(rss[-1]),
            "growth_mb_per_1000": growth_mb_per_1000(steps, rss),
            "open_files_before": files_before, "open_files_after": _open_files()}


def _websocket_client(port: int) -> socket.socket:
    """A client connected to the Meshcat at ``localhost:port`` by a WebSocket handshake
    (RFC 6455; the standard library suffices, the frames that follow are not read)."""
    client = socket.create_connection(("localhost", port), timeout=5.0)
    key = base64.b64encode(os.urandom(16)).decode()
    client.sendall((f"GET / HTTP/1.1\r\nHost: localhost:{port}\r\nUpgrade: websocket\r\n"
                    f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
                    "Sec-WebSocket-Version: 13\r\n\r\n").encode())
    answer = client.recv(4096)
    if not answer.startswith(b"HTTP/1.1 101"):
        client.close()
        raise RuntimeError(f"Meshcat refused the WebSocket handshake: {answer[:60]!r}")
    return client


def _wait_for(condition, seconds: float = 5.0) -> bool:
    """Whether ``condition()`` became true within ``seconds`` (polled every 10 ms)."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.01)
    return condition()


def _process_handles() -> dict:
    """This process' threads, open file descriptors and listening TCP sockets."""
    process = psutil.Process()
    return {"threads": process.num_threads(), "open_files": _open_files(),
            "listening_sockets": sum(1 for c in process.net_connections("tcp")
                                     if c.status == psutil.CONN_LISTEN)}


def meshcat_sessions(sessions: int, *, progress: bool = True) -> dict:
    """Open, use and drop ``sessions`` Meshcat servers in turn (module docstring)."""
    from pydrake.geometry import Box, Rgba
    from pydrake.math import RigidTransform

    from diagrams.meshcat import local_meshcat

    def session(k: int) -> tuple[bool, bool]:
        """(the client was counted, its connection was left open)."""
        meshcat = local_meshcat()
        client = _websocket_client(meshcat.port())
        counted = _wait_for(lambda: meshcat.GetNumActiveConnections() == 1)
        meshcat.SetObject("/box", Box(0.1, 0.1, 0.1), Rgba(0.2, 0.4, 0.8, 1.0))
        meshcat.SetTransform("/box", RigidTransform([0.0, 0.0, 0.01 * k]))
        meshcat.StaticHtml()
        client.close()
        left_open = not _wait_for(lambda: meshcat.GetNumActiveConnections() == 0)
        return counted, left_open

    def dropped(outcome: tuple[bool, bool]) -> tuple[bool, bool]:
        gc.collect()  # the session's server is gone once its frame is
        return outcome

    bar = tqdm(total=sessions, desc="Meshcat sessions", disable=not progress, leave=False)
    # the first server's one-time costs (threads, libraries) and the bar's thread apart
    dropped(session(-1))
    before, rss_before = _process_handles(), _rss_mb()
    outcomes = []
    for k in range(sessions):
        outcomes.append(dropped(session(k)))
        bar.update()
    bar.close()
    connected = sum(c for c, _ in outcomes)
    left_open = sum(o for _, o in outcomes)
    after = _process_handles()
    return {"sessions": sessions, "clients_connected": connected,
            "connections_left_open": left_open, "before": before, "after": after,
            "rss_mb_before": rss_before, "rss_mb_after": _rss_mb()}
