"""``cmanip``: a robot that manipulates objects under uncertainty by feeling them.

HERB (a Barrett WAM arm and BarrettHand) in Drake pushes objects on a table by touch:
manifold particle filters estimate the object's pose from contact, POMDP policies plan
under that uncertainty, and a visuo-tactile smoother tracks a pushed object from vision
and force. Commands:

    simulate    push an object straight ahead in a scene (replay.html, summary.json)
    run         one closed-loop episode: HERB pushes an object into the goal by touch
    configest   robot configuration estimation by touch in the HERB diagram (ch. 5)
    push        the pusher-slider rig: simulate a procedure into a log, estimate any log
    pomdp       write or solve Cassandra .pomdp files with the point-based solver
    bench       measurements (time step, filters, solvers, smoother)
    experiment  studies that reproduce the published figures and tables
    scenes      list the built-in scenes, objects and sensor layouts

Exit codes: 0 done; 2 bad input (the message names the file and the field); 3 an
infeasible start or push (the message says why).
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading

from cmanip import bench, configest, experiment, pomdp, push, run, scenes, simulate
from cmanip.options import HelpFormatter
from experiments.runner import TrialsInterrupted
from models.config import ConfigError

GROUPS = (simulate, run, configest, push, pomdp, bench, experiment, scenes)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="cmanip", description=__doc__,
                                     formatter_class=HelpFormatter)
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for group in GROUPS:
        group.register(commands)
    return parser


def interruptible() -> None:
    """Let Ctrl-C (SIGINT) reach the command even when it was started with SIGINT ignored,
    as a shell script's ``cmanip ... &`` is: a study so started stops cleanly on
    ``kill -INT``, keeping its finished trials, rather than running on."""
    if (threading.current_thread() is threading.main_thread()
            and signal.getsignal(signal.SIGINT) is signal.SIG_IGN):
        signal.signal(signal.SIGINT, signal.default_int_handler)


def main(argv: list[str] | None = None) -> int:
    interruptible()
    args = build_parser().parse_args(argv)
    try:
        return args.handler(args)
    except TrialsInterrupted as interrupted:
        print(f"cmanip: {interrupted}", file=sys.stderr)
        return 130
    except (ConfigError, ValueError, OSError) as err:
        print(f"cmanip: error: {err}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
