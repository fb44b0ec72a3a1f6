"""The command line as a new user meets it: help for every option, defaults shown,
Meshcat on localhost only, no wait for Enter without a terminal."""

import argparse

import pytest

from cmanip.cli import build_parser


def _parsers(parser, path=("cmanip",)):
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _parsers(sub, (*path, name))


def test_every_option_of_every_command_has_help_and_shows_its_default():
    missing = []
    for path, parser in _parsers(build_parser()):
        assert parser.description, f"{' '.join(path)} has no description"
        assert "%(default)s" in parser.formatter_class(prog="x")._get_help_string(
            argparse.Action(["--x"], "x", default=1, help="h")), "defaults not shown"
        for action in parser._actions:
            if isinstance(action, argparse._HelpAction | argparse._SubParsersAction):
                continue
            if not action.help:
                missing.append(f"{' '.join(path)} {'/'.join(action.option_strings) or action.dest}")
    assert not missing, "options without help: " + ", ".join(missing)


def test_the_top_level_description_says_what_the_program_does(capsys):
    with pytest.raises(SystemExit):
        build_parser().parse_args(["--help"])
    out = capsys.readouterr().out
    assert "manipulates objects under uncertainty" in out and "Exit codes" in out


def _listeners(port: int) -> list[str]:
    """Local addresses listening on ``port`` (IPv4 and IPv6), from /proc/net."""
    found = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        try:
            lines = open(table).read().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            local, state = line.split()[1], line.split()[3]
            address, hex_port = local.rsplit(":", 1)
            if state == "0A" and int(hex_port, 16) == port:
                found.append(address)
    return found


def test_meshcat_listens_on_the_loopback_interface_only():
    from diagrams.meshcat import local_meshcat

    meshcat = local_meshcat()
    addresses = _listeners(meshcat.port())
    assert addresses, "no listener found"
    loopback = {"0100007F", "00000000000000000000000001000000"}  # 127.0.0.1, ::1
    assert set(addresses) <= loopback, addresses


def test_no_wait_for_enter_without_a_terminal(monkeypatch, capsys):
    import io

    from cmanip.options import wait_for_meshcat

    monkeypatch.setattr("sys.stdin", io.StringIO(""))
    wait_for_meshcat("http://localhost:7000")  # would raise EOFError if it read
    assert "not a terminal" in capsys.readouterr().out
