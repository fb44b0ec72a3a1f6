"""``cmanip pomdp``: tabular POMDPs in Cassandra's ``.pomdp`` format: write a built-in
benchmark, or solve any file with the point-based solver."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from cmanip.options import subcommand

# the point-based solver's trial rules (PointBasedSolver.TRIAL_RULES, checked against this
# in the tests; not imported here, to keep `cmanip --help` free of the compiled solver)
TRIAL_RULES = ("sarsop", "hsvi")
BENCHMARKS = ("tiger", "tag", "rocksample_7_8")


def register(commands) -> None:
    pomdp = subcommand(commands, "pomdp", "write or solve Cassandra .pomdp files")
    kinds = pomdp.add_subparsers(dest="pomdp", required=True, metavar="ACTION")
    write = subcommand(kinds, "write", "write a built-in benchmark as a .pomdp file")
    write.add_argument("name", choices=BENCHMARKS, help="the benchmark")
    write.add_argument("--out", type=Path, required=True, help="the .pomdp file to write")
    write.set_defaults(handler=_write)
    solve = subcommand(kinds, "solve", "solve a .pomdp file with the point-based solver")
    solve.add_argument("file", type=Path, help="a Cassandra .pomdp file")
    solve.add_argument("--seconds", type=float, default=60.0, help="solver budget (s)")
    solve.add_argument("--trials", type=int, default=None,
                       help="also stop after this many search trials (a run that depends on "
                            "the file alone, not the machine)")
    solve.add_argument("--out", type=Path, default=None, help="write the policy (.npz)")
    solve.add_argument("--trial-rule", choices=TRIAL_RULES, default="sarsop",
                       help="where the solver's trials stop (HSVI2's rule: the comparison)")
    solve.add_argument("--no-progress", action="store_true", help="no progress bar")
    solve.set_defaults(handler=_solve)


def _write(args: argparse.Namespace) -> int:
    from planning.pomdp.benchmarks import rock_sample, tag, tiger
    from planning.pomdp.cassandra import write_pomdp

    model = {"tiger": tiger, "tag": tag, "rocksample_7_8": rock_sample}[args.name]()
    write_pomdp(model, args.out)
    S, A, n_obs = model.shape
    print(f"wrote {args.out}: {S} states, {A} actions, {n_obs} observations, "
          f"discount {model.discount}")
    return 0


def _solve(args: argparse.Namespace) -> int:
    from planning.pomdp.cassandra import read_pomdp
    from planning.pomdp.point_based import PointBasedSolver
    from planning.pomdp.progress import SolverProgressBar

    if args.seconds <= 0:
        raise ValueError(f"--seconds must be > 0, got {args.seconds}")
    if args.trials is not None and args.trials < 1:
        raise ValueError(f"--trials must be >= 1, got {args.trials}")
    model = read_pomdp(args.file)
    solver = PointBasedSolver(model, trial_rule=args.trial_rule)
    bar = SolverProgressBar(args.seconds, args.trials, disable=args.no_progress)
    start = time.perf_counter()
    policy = solver.solve(args.seconds, callback=bar, max_trials=args.trials)
    ran_s = time.perf_counter() - start
    bar.close()
    lower, upper = solver.report.history[-1][1:]
    print(f"{args.file}: bounds at the initial belief [{lower:.4f}, {upper:.4f}] after "
          f"{ran_s:.1f} s and {solver.report.trials} trials (budget {args.seconds:g} s"
          f"{f', {args.trials} trials' if args.trials else ''}); "
          f"{len(policy.alphas)} alpha-vectors")
    if args.out:
        policy.save(args.out)
        print(f"wrote {args.out}")
    return 0
