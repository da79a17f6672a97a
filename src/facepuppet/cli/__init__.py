"""The `facepuppet` command: argument parsing only; every subcommand is a thin call into the library.

Each subcommand lives in a module ``facepuppet.cli._<name>`` with ``register(subparsers)``, which adds its
parser and sets ``run=function(args) -> int`` as its default, and declares its file arguments
(``inputs`` / ``outputs``, see :mod:`facepuppet.cli._paths`), checked together before ``run`` starts.
Every failure becomes one line on stderr naming the file or argument (:func:`error_line`) and a non-zero exit;
SIGINT, SIGTERM and SIGHUP stop the command cleanly (:mod:`facepuppet._util.interrupt`) with exit 128 + the
signal's number.
"""

from __future__ import annotations

import argparse
import errno
import importlib
import logging
import os
import sys
import warnings

from facepuppet import __version__
from facepuppet._util.interrupt import Interrupted, handle_signals
from facepuppet.cli._paths import check_args, describe
from facepuppet.errors import FacepuppetError

__all__ = ["main", "error_line"]

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


def error_line(e: BaseException) -> str:
    """One line saying what failed: the file and the reason for an OSError, the message otherwise."""
    if isinstance(e, OSError) and e.strerror:
        reason = e.strerror
        if e.errno == errno.ENOSPC:
            reason += " (disk full)"
        name = e.filename if e.filename is not None else None
        if name is None:
            text = reason
        else:
            text = f"{describe(os.fsdecode(name))}: {reason}"
            if e.filename2 is not None:
                text = f"{describe(os.fsdecode(e.filename2))}: {reason} (from {describe(os.fsdecode(name))})"
    elif isinstance(e, MemoryError):
        text = "out of memory" + (f" ({e})" if str(e) else "") + "; the input asks for more than this machine has"
    elif isinstance(e, (FacepuppetError, ValueError)):
        text = str(e)
    else:
        text = f"{type(e).__name__}: {e}"
    return describe(" ".join(text.split()))


def _quiet_libraries(verbose: bool) -> None:
    """OpenCV's and FFmpeg's own warnings would print before (and instead of) our one line."""
    if not verbose:
        os.environ.setdefault("OPENCV_LOG_LEVEL", "SILENT")   # its errors are said in our own line
        os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")
        # NumPy's floating-point warnings (a damaged file's overflow) would print before the one line
        warnings.filterwarnings("ignore", category=RuntimeWarning)


def main(argv: list[str] | None = None) -> int:
    """Run the command line; returns the exit code (0 success, 1 failure, 2 usage error, 128 + N on signal N)."""
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING,
                        format="%(levelname)s %(name)s: %(message)s")
    if not getattr(args, "run", None):
        parser.print_help()
        return 2
    _quiet_libraries(args.verbose)
    try:
        with handle_signals():
            check_args(args)
            code = int(args.run(args) or 0)
            sys.stdout.flush()
            return code
    except Interrupted as e:
        print(f"facepuppet {args.command}: interrupted ({e.name}); nothing written", file=sys.stderr)
        return e.exit_code
    except KeyboardInterrupt:
        print(f"facepuppet {args.command}: interrupted; nothing written", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # stdout went away (``| head``): say so once on stderr, and keep Python from failing on it at exit
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        except (OSError, ValueError):
            pass
        print(f"facepuppet {args.command}: error: stdout: broken pipe (the reader of the output went away)",
              file=sys.stderr)
        return 1
    except Exception as e:  # noqa: BLE001 - the CLI's contract: one line, never a traceback
        cause = e.__cause__ or e.__context__
        if isinstance(cause, Interrupted):   # raised inside compiled code's C wrapper (SystemError)
            print(f"facepuppet {args.command}: interrupted ({cause.name}); nothing written", file=sys.stderr)
            return cause.exit_code
        if args.verbose:
            logging.exception("failed")
        print(f"facepuppet {args.command}: error: {error_line(e)}", file=sys.stderr)
        return 1
