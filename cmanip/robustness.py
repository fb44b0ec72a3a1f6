"""``cmanip bench robustness``: the parts measured and the report's summary keys.

Parts: ``malformed`` (:mod:`cmanip.malformed`), ``faults``
(:mod:`experiments.fault_bench`), ``budgets`` and ``memory``
(:mod:`experiments.load_bench`). The report holds each part's details and, at its top,
``malformed_tried``, ``malformed_clear_error``, ``malformed_ignored``, ``faults_injected``,
``faults_recovered``
(the robust filters, with the outlier gate and, for the MPFs, the evidence split;
``faults_recovered_plain``: the filters as
the thesis has them; ``sham_recovered`` of ``sham_runs``: the recovery rule's pass rate
without a fault, its baseline; ``lasting_harm``: the pooled rank test of
:func:`experiments.fault_bench.lasting_harm`),
``budget_overrun_ms_p99`` (the worse planner's p99 overrun under load) and
``memory_growth_mb_per_1000_steps`` (the worse of the two long runs) and
``meshcat_connections_leaked`` (of :data:`MESHCAT_SESSIONS` sessions with a client each).
"""

from __future__ import annotations

from pathlib import Path

ROBUSTNESS_PARTS = ("malformed", "faults", "budgets", "memory")

MESHCAT_SESSIONS = 20
"""Meshcat servers opened, used and dropped in turn by the ``memory`` part."""


def measure_robustness(parts, *, limit_per_kind: int | None = None, fault_trials: int = 3,
                       decisions: int = 200, budget_s: float = 0.1,
                       smoother_updates: int = 10_000, cache_dir: Path | None = None,
                       seed: int = 0, progress: bool = True, backend=None,
                       fault_figure: Path | None = None) -> dict:
    """Measure ``parts`` and print a summary of each; the report (module docstring).
    ``backend`` (an :class:`experiments.runner.Backend`; None: the fault bench's
    default, serial) runs the fault part's jobs; the budgets and memory parts measure
    this process and stay in it. ``fault_figure``: where to draw the fault part's
    outcomes (PNG, :func:`experiments.fault_plots.plot_fault_recovery`)."""
    report: dict = {}
    if "malformed" in parts:
        from cmanip.malformed import measure

        malformed = measure(limit_per_kind=limit_per_kind, progress=progress)
        report.update(malformed)
        print(f"malformed inputs: {malformed['malformed_tried']} tried, "
              f"{malformed['malformed_clear_error']} clear errors naming the file, "
              f"{malformed['malformed_accepted']} loaded (a legal variation or a silent "
              f"default; listed under accepted_cases; {malformed['malformed_ignored']} of "
              f"them with a changed value the loader ignored, under ignored_cases), "
              f"{malformed['malformed_other']} other (listed under other_cases)")
        for kind, entry in malformed["kinds"].items():
            print(f"  {kind:32s} {entry['tried']:5d} tried, {entry['clear_error']:5d} clear, "
                  f"{entry['accepted']:4d} loaded, {entry['other']:3d} other")
    if "faults" in parts:
        report.update(_faults(fault_trials, seed, progress, backend))
        if fault_figure is not None:
            from experiments.fault_plots import plot_fault_recovery

            fault_figure.parent.mkdir(parents=True, exist_ok=True)
            plot_fault_recovery(report["fault_outcomes"], report["lasting_harm"], fault_figure)
            print(f"wrote {fault_figure}")
    if "budgets" in parts:
        report.update(_budgets(decisions, budget_s, cache_dir, seed, progress))
    if "memory" in parts:
        report.update(_memory(5 * decisions, smoother_updates, seed, progress))
    return report


def _faults(trials: int, seed: int, progress: bool, backend) -> dict:
    from experiments.fault_bench import SHAM, measure_faults

    faults = measure_faults(trials=trials, seed=seed, progress=progress,
                            **({} if backend is None else {"backend": backend}))
    outcomes = faults["fault_outcomes"]
    print(f"faults: {faults['faults_injected']} injected, {faults['faults_recovered']} "
          f"recovered by the robust filters ({faults['faults_recovered_plain']} by the "
          f"thesis' filters), {faults['faults_non_finite']} with a non-finite estimate; "
          f"{faults['faults_reported']} of {faults['faults_non_finite_input']} non-finite "
          f"inputs reported; the sham (no fault) passes the rule in "
          f"{faults['sham_recovered']} of {faults['sham_runs']} runs")
    for variant, rates in faults["unrecovered_rates"].items():
        print(f"  {variant} filters fail the rule: " + ", ".join(
            f"{kind} {r['failed']}/{r['runs']} ({100 * r['rate']:.0f} % "
            f"[{100 * r['ci95'][0]:.0f}, {100 * r['ci95'][1]:.0f}])"
            for kind, r in rates.items()))
    harm = faults["lasting_harm"]
    for variant, shams in harm["shams"].items():
        sham = shams["all"]
        print(f"  {variant} filters, rank of a run's last-quarter error among its "
              f"{harm['draws']} clean draws (0.5: a clean draw; shams {sham['mean_rank']:.2f} "
              f"+- {sham['ci95']:.2f}, p {sham['p_one_sided']:.2f}):")
        every = harm["faults"][variant]["all"]
        print(f"    every fault {every['mean_rank']:.2f}{' HARMED' if every['harmed'] else ''}"
              f" over {every['runs']} runs: at most "
              f"{100 * every['harmed_share_upper95']:.0f} % of them left above all their "
              f"clean draws (95 %); per group, mean rank (that bound):")
        for grouping in ("by_estimator", "by_fault"):
            print("    " + ", ".join(
                f"{group} {c['mean_rank']:.2f} ({100 * c['harmed_share_upper95']:.0f} %)"
                f"{' HARMED' if c['harmed'] else ''}"
                for group, c in harm[grouping].get(variant, {}).items()))
    by = {}
    for o in outcomes:
        if o["fault"] == SHAM:
            continue
        key = (o["estimator"], o["robust"])
        done, total = by.get(key, (0, 0))
        by[key] = (done + o["recovered"], total + 1)
    for (estimator, robust), (done, total) in by.items():
        variant = "" if estimator == "smoother" else "robust" if robust else "thesis"
        print(f"  {estimator:16s} {variant:6s}: {done}/{total} recovered")
    return faults


def _budgets(decisions: int, budget_s: float, cache_dir, seed: int, progress: bool) -> dict:
    from experiments.load_bench import despot_budget, lat_despot_budget

    budgets = {"despot_tag": despot_budget(decisions, budget_s, seed=seed, progress=progress),
               "lat_despot_cul_de_sac": lat_despot_budget(decisions, budget_s, seed=seed,
                                                          cache_dir=cache_dir,
                                                          progress=progress)}
    for name, entry in budgets.items():
        for load in ("idle", "loaded"):
            e = entry[load]
            print(f"budget {name} {load}: overrun p50 {e['overrun_ms_p50']:.1f} ms, p99 "
                  f"{e['overrun_ms_p99']:.1f} ms, max {e['overrun_ms_max']:.1f} ms at "
                  f"{entry['budget_ms']:.0f} ms (allowed p99 {e['allowed_p99_ms']:.1f} ms: "
                  f"{'within' if e['within_budget'] else 'OVER'})")
    return {"budgets": budgets,
            "budget_overrun_ms_p99": max(e["loaded"]["overrun_ms_p99"]
                                         for e in budgets.values()),
            "budget_overrun_ms_max": max(e["loaded"]["overrun_ms_max"]
                                         for e in budgets.values()),
            "budgets_within": all(e[load]["within_budget"] for e in budgets.values()
                                  for load in ("idle", "loaded"))}


def _memory(decisions: int, updates: int, seed: int, progress: bool) -> dict:
    from experiments.load_bench import closed_loop_memory, meshcat_sessions, smoother_memory

    memory = {"closed_loop": closed_loop_memory(decisions, seed=seed, progress=progress),
              "smoother": smoother_memory(updates, seed=seed, progress=progress)}
    for name, entry in memory.items():
        print(f"memory {name}: {entry['rss_mb_start']:.0f} -> {entry['rss_mb_end']:.0f} MB, "
              f"growth {entry['growth_mb_per_1000']:+.2f} MB per 1000 steps; open files "
              f"{entry['open_files_before']} -> {entry['open_files_after']}")
    meshcat = meshcat_sessions(MESHCAT_SESSIONS, progress=progress)
    b, a = meshcat["before"], meshcat["after"]
    print(f"Meshcat: {meshcat['sessions']} sessions, {meshcat['clients_connected']} clients "
          f"connected, {meshcat['connections_left_open']} connections left open; threads "
          f"{b['threads']} -> {a['threads']}, open files {b['open_files']} -> "
          f"{a['open_files']}, listening sockets {b['listening_sockets']} -> "
          f"{a['listening_sockets']}")
    return {"memory": {**memory, "meshcat": meshcat},
            "memory_growth_mb_per_1000_steps": max(e["growth_mb_per_1000"]
                                                   for e in memory.values()),
            "meshcat_connections_leaked": meshcat["connections_left_open"]}
