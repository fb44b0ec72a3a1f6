"""What every ``cmanip`` command shares: the help format, options whose defaults live in a
settings dataclass, the Meshcat wait, and writing a report."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


class HelpFormatter(argparse.ArgumentDefaultsHelpFormatter,
                    argparse.RawDescriptionHelpFormatter):
    """Shows each option's default after its help, and descriptions as written."""


def subcommand(parent, name: str, help: str, description: str | None = None):
    """A sub-parser of ``parent`` with :class:`HelpFormatter`."""
    return parent.add_parser(name, help=help, description=description or help,
                             formatter_class=HelpFormatter)


def runner_options(parser, *, resume: bool = True) -> None:
    """Where a study's trials run and (with ``resume``) whether it picks up a killed run:
    ``--backend serial|processes|ray``, ``--workers N``, ``--address HOST:PORT|auto`` (a Ray
    cluster) and ``--resume``; read back by :func:`backend_of`."""
    parser.add_argument("--backend", choices=("serial", "processes", "ray"),
                        default="processes",
                        help="where trials run: this process, a local process pool, or Ray "
                             "(local, or the cluster at --address)")
    workers_option(parser, "worker processes (processes) or CPUs (local ray)")
    parser.add_argument("--address", default=None,
                        help="a Ray cluster to run on (HOST:PORT or auto; ray backend)")
    if resume:
        parser.add_argument("--resume", action="store_true",
                            help="keep the finished trials in OUT/trials.jsonl and run only "
                                 "the missing ones (same settings required)")


def backend_of(args: argparse.Namespace):
    """The :class:`experiments.runner.Backend` the runner options ask for."""
    from experiments.runner import Backend

    return Backend(args.backend, args.workers, args.address)


def workers_option(parser, what: str = "processes") -> None:
    """``--workers N`` (N >= 1; default 1): how many processes run a study's trials; the
    results do not depend on it. A value below 1 is a usage error (exit 2)."""
    def count(text: str) -> int:
        value = int(text)
        if value < 1:
            raise argparse.ArgumentTypeError(f"must be >= 1, got {value}")
        return value

    parser.add_argument("--workers", type=count, default=1,
                        help=f"{what} (the results do not depend on it)")


def setting_option(parser, flag: str, default, help: str, **kwargs) -> None:
    """An option that overrides a setting only when given: its value defaults to
    ``argparse.SUPPRESS`` (absent from the namespace), and its help shows the setting's
    default, read from the settings dataclass (the one place it is written)."""
    parser.add_argument(flag, default=argparse.SUPPRESS,
                        help=f"{help} (default: {default})", **kwargs)


def check_outlier_gate(args: argparse.Namespace) -> None:
    """Refuse an ``--outlier-gate`` (a log evidence) that is not below 0, naming the flag.

    Raises:
        ValueError: the gate given and >= 0.
    """
    gate = vars(args).get("outlier_gate")
    if gate is not None and not gate < 0:
        raise ValueError(f"--outlier-gate must be < 0, got {gate}")


def wait_for_meshcat(url: str) -> None:
    """Keep the live Meshcat up until Enter, when a terminal can answer; otherwise say so
    and return (a pipe or a batch job has no Enter to give)."""
    if sys.stdin is not None and sys.stdin.isatty():
        input(f"Meshcat stays up at {url} until you press Enter... ")
    else:
        print("standard input is not a terminal: not waiting; the recording is in "
              "replay.html", flush=True)


def write_json(report: dict, path: Path | None) -> None:
    """Write ``report`` to ``path`` (if given) as indented JSON."""
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(report, indent=2) + "\n")
