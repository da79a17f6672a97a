"""The `facepuppet` command: argument parsing only; every subcommand is a thin call into the library.

Each subcommand lives in a module ``facepuppet.cli._<name>`` with ``register(subparsers)``, which adds its
parser and sets ``run=function(args) -> int`` as its default.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys

from facepuppet import __version__
from facepuppet.errors import FacepuppetError

__all__ = ["main"]

#: Subcommands in the order `facepuppet --help` lists them.
COMMANDS = ("demo", "track", "calibrate", "rig", "animate", "batch", "live")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="facepuppet",
        description="Performance-driven facial animation from one ordinary camera.",
        epilog="The journey: 'calibrate' captures the performer's key expressions (and with --train-profile "
               "trains the colour tracker's performer profile), 'rig' pairs them with the character's "
               "key-models and fits the mapping, 'animate' maps a performance onto the character. 'track' "
               "writes the tracked features of any video; 'demo' runs the whole chain on built-in data.",
    )
    parser.add_argument("--version", action="version", version=f"facepuppet {__version__}")
    parser.add_argument("-v", "--verbose", action="store_true", help="log what happens")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        try:
            module = importlib.import_module(f"facepuppet.cli._{name}")
        except ModuleNotFoundError as e:
            if e.name != f"facepuppet.cli._{name}":
                raise
            continue
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit code (0 success, 1 failure, 2 usage error)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    if not getattr(args, "run", None):
        parser.print_help()
        return 2
    try:
        return int(args.run(args) or 0)
    except KeyboardInterrupt:
        print("facepuppet: interrupted", file=sys.stderr)
        return 130
    except (FacepuppetError, ValueError, TypeError, FileNotFoundError, PermissionError, IsADirectoryError) as e:
        if args.verbose:
            logging.exception("failed")
        print(f"facepuppet {args.command}: error: {e}", file=sys.stderr)
        return 1
