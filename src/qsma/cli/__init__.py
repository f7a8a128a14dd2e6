"""Command line: ``qsma run`` and ``qsma modes``. The only place that prints.

Exit codes: 0 success, 1 analysis failed, 2 bad input.
"""
from __future__ import annotations

import argparse
import signal
import sys
import threading
import traceback
import warnings

from ..errors import AnalysisError, ContactConvergenceWarning, InputError, QSMAError
from . import modes as _modes, run as _run, sweep as _sweep

EXIT_OK, EXIT_FAILED, EXIT_INPUT = 0, 1, 2
SUBCOMMANDS = {"run": _run, "modes": _modes, "sweep": _sweep}


def build_parser():
    from .. import __version__
    parser = argparse.ArgumentParser(
        prog="qsma", description="Quasi-static modal analysis of jointed structures.",
        epilog="exit codes: 0 success, 1 analysis failed, 2 bad input")
    parser.add_argument("--version", action="version", version=f"qsma {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    for name, module in SUBCOMMANDS.items():
        p = sub.add_parser(name, help=module.HELP, description=module.HELP)
        module.add_arguments(p)
        p.add_argument("--debug", action="store_true",
                       help="show Python tracebacks of errors")
    return parser


def _terminate(signum, frame):
    raise KeyboardInterrupt            # unwinds: temporary result files are removed


def main(argv=None) -> int:
    """Run the command line; returns the exit code (0 ok, 1 analysis failed, 2 bad input)."""
    if threading.current_thread() is not threading.main_thread():
        return _main(argv)
    previous = signal.signal(signal.SIGTERM, _terminate)
    try:
        return _main(argv)
    finally:
        signal.signal(signal.SIGTERM, previous)


def _main(argv):
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:           # argparse: usage error (2) or --help/--version (0)
        return int(exc.code or 0)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ContactConvergenceWarning)  # reported by the CLI
            return SUBCOMMANDS[args.command].execute(args)
    except InputError as exc:
        _report(args, exc, "error")
        return EXIT_INPUT
    except AnalysisError as exc:
        _report(args, exc, "analysis failed")
        return EXIT_FAILED
    except QSMAError as exc:
        _report(args, exc, "error")
        return EXIT_FAILED
    except Exception as exc:            # a bug of ours, not a user mistake
        _report(args, exc, "internal error (please report it; --debug shows where)")
        return EXIT_FAILED
    except KeyboardInterrupt:
        print("qsma: interrupted", file=sys.stderr)
        return 130


def _report(args, exc, what):
    if getattr(args, "debug", False):
        traceback.print_exc()
    text = str(exc) or type(exc).__name__
    print(f"qsma: {what}: {text}", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
