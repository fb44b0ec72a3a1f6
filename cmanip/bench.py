"""``cmanip bench``: measurements, each reported as medians (and ratios against a baseline
measured in the same run where there is one) and optionally written as JSON."""

from __future__ import annotations

import argparse
from pathlib import Path

from cmanip.options import subcommand, write_json
from cmanip.pomdp import TRIAL_RULES


def register(commands) -> None:
    bench = subcommand(commands, "bench", "measurements: plant time step, filters, POMDP "
                                          "solver, visuo-tactile smoother")
    kinds = bench.add_subparsers(dest="bench", required=True, metavar="BENCH")
    step = subcommand(kinds, "timestep", "accuracy and speed per plant time step")
    step.add_argument("--steps", type=float, nargs="+",
                      default=[0.001, 0.002, 0.005, 0.01, 0.02], help="time steps (s)")
    step.add_argument("--repeats", type=int, default=3, help="timed runs per step")
    _json(step)
    step.set_defaults(handler=_timestep)

    mpf = subcommand(kinds, "mpf", "CPF/MPF update times, pushing-model throughput")
    mpf.add_argument("--repeats", type=int, default=30, help="timed updates per filter")
    mpf.add_argument("--seed", type=int, default=0, help="seeds the particles")
    _json(mpf)
    mpf.set_defaults(handler=_mpf)

    pomdp = subcommand(kinds, "pomdp", "point-based solver bounds on Tag and RockSample(7,8) "
                                       "over 300 s, against the C++ SARSOP's published runs")
    pomdp.add_argument("--quick", action="store_true", help="stop at 30 s")
    pomdp.add_argument("--trial-rule", choices=TRIAL_RULES, default="sarsop",
                       help="where the solver's trials stop (HSVI2's rule: the comparison)")
    _json(pomdp)
    pomdp.set_defaults(handler=_pomdp)

    vt = subcommand(kinds, "visuotactile", "smoother update and relinearisation times")
    vt.add_argument("--log", type=Path, default=None,
                    help="time on this push log (default: a simulated standard run)")
    vt.add_argument("--object", default="rect1", help="the log's object")
    vt.add_argument("--seed", type=int, default=0, help="seeds the simulated run")
    _json(vt)
    vt.set_defaults(handler=_visuotactile)


def _json(parser) -> None:
    parser.add_argument("--json", type=Path, default=None, help="also write the report here")


def _timestep(args: argparse.Namespace) -> int:
    from experiments.timestep_bench import run_timestep_bench

    write_json(run_timestep_bench(args.steps, repeats=args.repeats), args.json)
    return 0


def _mpf(args: argparse.Namespace) -> int:
    from experiments.mpf_bench import run_mpf_bench

    write_json(run_mpf_bench(repeats=args.repeats, seed=args.seed), args.json)
    return 0


def _pomdp(args: argparse.Namespace) -> int:
    from experiments.pomdp_bench import run_pomdp_bench

    write_json(run_pomdp_bench(quick=args.quick, trial_rule=args.trial_rule), args.json)
    return 0


def _visuotactile(args: argparse.Namespace) -> int:
    from experiments.visuotactile_bench import run_visuotactile_bench

    write_json(run_visuotactile_bench(args.log, args.seed, args.object), args.json)
    return 0
