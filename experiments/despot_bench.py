"""``cmanip bench despot``: DESPOT on the field's benchmarks, side by side with the
reference C++ DESPOT (AdaCompNUS/despot) built on the same machine.

For each problem and per-decision budget: the mean discounted return with its 95 %
half-width over ``episodes`` episodes of at most ``steps`` decisions (the reference's
simulation length, 90), the decision time p50/p99/max (ms) and the largest overrun of the
budget, trials and tree nodes per second of search, belief recoveries and bound crossings
repaired, and the process' peak resident memory. Episode e of a (problem, budget) is seeded
from (seed, e), so the runs are reproducible up to the wall-clock budget.

With ``reference`` (the ``build_cmake`` folder of a built reference, or any folder under
which ``despot_tag`` and ``despot_rock_sample`` are found) the reference runs the same
problem and budget for the same number of episodes (``--runs``, seeded ``-r seed``) with
its default bounds, and its mean and 95 % half-width (1.96 times its printed standard
error) are reported beside ours. Its budget is CPU time (``clock()``), ours wall-clock.
"""

from __future__ import annotations

import re
import resource
import subprocess
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from experiments.statistics import half_width
from planning.pomdp.despot import DespotSettings
from planning.pomdp.online import DespotPlanner, run_episode
from planning.pomdp.problems import load_problem

REFERENCE_BINARIES = {"tag": "despot_tag", "rocksample": "despot_rock_sample"}
_AVERAGE = re.compile(r"Average total discounted reward \(stderr\) = (\S+) \((\S+)\)")


def run_despot_bench(problems: list[str], budgets_s: list[float], *, episodes: int = 100,
                     steps: int = 90, seed: int = 0, scenarios: int = 500,
                     particles: int = 1000, reference: Path | None = None,
                     progress: bool = True) -> dict:
    """``{problem: {str(seconds): report}}`` (see the module docstring); prints a line
    per (problem, budget)."""
    report: dict = {}
    for name in problems:
        model = load_problem(name)
        report[name] = {}
        for budget in budgets_s:
            ours = _ours(model, name, budget, episodes=episodes, steps=steps, seed=seed,
                         scenarios=scenarios, particles=particles, progress=progress)
            line = (f"{name} at {budget:g} s: DESPOT {ours['discounted_return_mean']:.2f} "
                    f"+- {ours['discounted_return_ci95']:.2f} over {episodes} episodes; "
                    f"decision p50 {ours['decision_ms_p50']:.0f} ms, overrun max "
                    f"{ours['budget_overrun_ms_max']:.0f} ms; "
                    f"{ours['trials_per_s']:.0f} trials/s")
            if reference is not None:
                ours["reference"] = run_reference(reference, name, budget, episodes, seed)
                ref = ours["reference"]
                line += (f" | reference {ref['discounted_return_mean']:.2f} +- "
                         f"{ref['discounted_return_ci95']:.2f} ({ref['wall_s']:.0f} s)")
            print(line, flush=True)
            report[name][f"{budget:g}"] = ours
    return report


def _ours(model, name, budget, *, episodes, steps, seed, scenarios, particles,
          progress) -> dict:
    planner = DespotPlanner(model, DespotSettings(scenarios=scenarios, seconds=budget))
    returns, decision_ms, overrun_ms = [], [], []
    trials = nodes = search_s = 0.0
    recoveries = crossings = 0
    start = time.perf_counter()
    for e in tqdm(range(episodes), desc=f"{name} {budget:g} s", unit="episode",
                  disable=not progress, leave=False):
        episode = run_episode(model, planner, rng=np.random.default_rng((seed, e)),
                              steps=steps, particles=particles)
        returns.append(episode.discounted_return)
        decision_ms.extend(episode.decision_ms)
        overrun_ms.extend(episode.overrun_ms)
        trials += episode.trials.sum()
        nodes += episode.nodes.sum()
        search_s += episode.decision_ms.sum() / 1e3
        recoveries += episode.recoveries
        crossings += episode.crossings_repaired
    returns = np.asarray(returns)
    half = half_width(returns)
    decision_ms = np.asarray(decision_ms)
    return {
        "discounted_return_mean": float(returns.mean()),
        "discounted_return_ci95": float(half),
        "episodes": int(len(returns)),
        "decisions": int(len(decision_ms)),
        "decision_ms_p50": float(np.percentile(decision_ms, 50)),
        "decision_ms_p99": float(np.percentile(decision_ms, 99)),
        "decision_ms_max": float(decision_ms.max()),
        "budget_overrun_ms_max": float(np.max(overrun_ms)),
        "trials_per_s": float(trials / max(search_s, 1e-9)),
        "nodes_per_s": float(nodes / max(search_s, 1e-9)),
        "belief_recoveries": int(recoveries),
        "crossings_repaired": int(crossings),
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        "wall_s": time.perf_counter() - start,
        "scenarios": scenarios, "particles": particles, "steps": steps,
    }


def find_reference(directory: Path, problem: str) -> Path:
    """The reference executable for ``problem`` under ``directory``."""
    binary = REFERENCE_BINARIES[problem.split(":")[0]]
    found = sorted(p for p in Path(directory).rglob(binary) if p.is_file())
    if not found:
        raise FileNotFoundError(f"{directory}: no {binary} below it (build the reference "
                                f"DESPOT's examples first)")
    return found[0]


def run_reference(directory: Path, problem: str, budget: float, episodes: int,
                  seed: int) -> dict:
    """Run the reference on ``problem`` (``tag`` or ``rocksample:N:K``) for ``episodes``
    runs at ``budget`` s per step; its mean, 95 % half-width and wall time."""
    if problem.split(":")[0] not in REFERENCE_BINARIES:
        raise ValueError(f"the reference runs tag and rocksample:N:K, not {problem!r}")
    command = [str(find_reference(directory, problem)), "-t", f"{budget:g}", "--runs",
               str(episodes), "-r", str(seed)]
    if problem.startswith("rocksample"):
        _, size, rocks = problem.split(":")
        command += ["--size", size, "--number", rocks]
    start = time.perf_counter()
    output = subprocess.run(command, capture_output=True, text=True, check=True,
                            timeout=max(3600.0, 200 * budget * episodes)).stdout
    match = _AVERAGE.search(output)
    if match is None:
        raise RuntimeError(f"{command[0]}: no average in its output")
    mean, stderr = float(match.group(1)), float(match.group(2))
    return {"discounted_return_mean": mean, "discounted_return_ci95": 1.96 * stderr,
            "episodes": episodes, "wall_s": time.perf_counter() - start,
            "command": " ".join(command)}
