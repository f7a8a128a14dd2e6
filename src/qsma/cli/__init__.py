"""Command line: ``qsma run``, ``modes``, ``sweep``, ``fit``, ``init``, ``export`` and
``examples``.
The only place that prints.

Exit codes: 0 success, 1 analysis failed (or results could not be written), 2 bad
input (including an output folder in use by another run), 130 interrupted
(SIGTERM, SIGINT / Ctrl-C).
"""
from __future__ import annotations

import argparse
import logging
import os
import signal
import sys
import threading
import traceback
import warnings

from ..errors import (AnalysisError, ContactConvergenceWarning, InputError, QSMAError,
                      QSMAWarning)
from . import examples as _examples, export as _export, fit as _fit, init as _init, \
    modes as _modes, run as _run, sweep as _sweep
from .progress import LOG_LEVELS, LogSetup
from ..version import __version__

EXIT_OK, EXIT_FAILED, EXIT_INPUT = 0, 1, 2
#: 128 + SIGINT, the shell convention for a command stopped by Ctrl-C; also used for
#: SIGTERM so that scripts see one code for "interrupted"
EXIT_INTERRUPTED = 130
SUBCOMMANDS = {"run": _run, "modes": _modes, "sweep": _sweep, "fit": _fit, "init": _init,
               "export": _export, "examples": _examples}


def build_parser():
    parser = argparse.ArgumentParser(
        prog="qsma", description="Quasi-static modal analysis of jointed structures.",
        epilog="exit codes: 0 success, 1 analysis failed or results not written, "
               "2 bad input or output folder in use, 130 interrupted")
    parser.add_argument("--version", action="version", version=f"qsma {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    for name, module in SUBCOMMANDS.items():
        p = sub.add_parser(name, help=module.HELP, description=module.HELP)
        module.add_arguments(p)
        p.add_argument("--debug", action="store_true",
                       help="show Python tracebacks of errors")
        p.add_argument("--log-level", choices=LOG_LEVELS, default="warning",
                       help="qsma's log messages shown on stderr from this level on "
                            "(default warning; info: refinements, fallbacks, the "
                            "processes used); a run also writes them to qsma.log in "
                            "its result folder (info and above)")
    return parser


#: Subcommands after which the process holds nothing to tear down (no worker
#: processes, no open clients; every result file written, flushed and renamed into
#: place): run as the process itself, they leave by ``os._exit`` once stdout and
#: stderr are flushed. The interpreter's own teardown (clearing the modules of numpy,
#: scipy and matplotlib, collecting their objects) took 0.3-0.45 s of CPU after a
#: sandwich-2d run, a tenth of the process (CHANGELOG.md, "The small case").
FAST_EXIT = frozenset({"run"})


class _Process:
    """The subcommand this process ran (set by :func:`_main`)."""

    command = None


class _Interrupt:
    """Set by the SIGTERM / SIGINT handler. Code we call (matplotlib, meshio, C
    extensions) may swallow the ``KeyboardInterrupt`` the handler raises or turn it
    into another exception; the flag makes any outcome after a signal exit 130."""

    signum = None


def _terminate(signum, frame):
    _Interrupt.signum = signum
    raise KeyboardInterrupt            # unwinds: the staging folder is removed


def main(argv=None, *, fast_exit=False) -> int:
    """Run the command line; returns the exit code (0 ok, 1 analysis failed or results
    not written, 2 bad input, 130 interrupted).

    ``fast_exit``: set only by the process entry points (:func:`entry`, ``python -m
    qsma``): after a subcommand of :data:`FAST_EXIT` the process then leaves by
    ``os._exit`` once its output is flushed. A program that calls ``main()`` itself
    always gets the exit code back, with its own teardown (atexit handlers, open
    files) untouched."""
    if threading.current_thread() is not threading.main_thread():
        return _main(argv)
    _Interrupt.signum = None
    previous = {s: signal.signal(s, _terminate) for s in (signal.SIGTERM, signal.SIGINT)}
    try:
        code = _main(argv)
    except KeyboardInterrupt:          # a signal during the error report itself
        code = _interrupted()
    finally:
        for s, handler in previous.items():
            # the process itself (argv from sys.argv) exits next: a signal while the
            # interpreter shuts down exits 130 too, instead of dying by the signal
            signal.signal(s, _exit_now if argv is None else handler)
    if argv is None and code == EXIT_INTERRUPTED:
        # CPython kills itself with SIGINT at exit (status -2, not 130) when the
        # KeyboardInterrupt went through C code that ran Python code (e.g. an import of
        # a compiled module), even though we handled it: leave directly instead
        _exit_now(None, None, message=False)
    if fast_exit and argv is None and _Process.command in FAST_EXIT:
        _exit_now(None, None, message=False, code=code)
    return code


def entry() -> int:
    """The ``qsma`` console script: :func:`main` as the process itself."""
    return main(fast_exit=True)


def _exit_now(signum, frame, message=True, code=EXIT_INTERRUPTED):
    """Flush stdout and stderr and end the process with ``code`` at once (no
    interpreter teardown). Logging handlers that a program may have configured are
    flushed and closed first."""
    try:
        logging.shutdown()
    except Exception:                    # a broken handler must not block the exit
        pass
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError, RuntimeError):
            pass
    if message:
        os.write(2, b"qsma: interrupted\n")
    os._exit(code)


def _interrupted():
    print("qsma: interrupted", file=sys.stderr)
    return EXIT_INTERRUPTED


def _main(argv):
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:           # argparse: usage error (2) or --help/--version (0)
        return int(exc.code or 0)
    _Process.command = args.command
    args.log = LogSetup(args.log_level)
    try:
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("ignore", ContactConvergenceWarning)  # reported by the CLI
            warnings.simplefilter("always", QSMAWarning)
            try:
                code = SUBCOMMANDS[args.command].execute(args)
            finally:
                _print_warnings(seen)
        return EXIT_INTERRUPTED if _Interrupt.signum is not None else code
    except KeyboardInterrupt:
        return _interrupted()
    except BaseException as exc:
        if _Interrupt.signum is not None:   # the signal surfaced as another exception
            return _interrupted()
        return _exit_code(args, exc)
    finally:
        args.log.close()


def _print_warnings(seen):
    """Print the warnings of our own classes meant for the user; others are re-emitted."""
    printed = set()
    for w in seen:
        if issubclass(w.category, QSMAWarning):
            if str(w.message) not in printed:       # e.g. one line for two equal bodies
                print(f"qsma: warning: {w.message}", file=sys.stderr)
                printed.add(str(w.message))
        else:
            warnings.showwarning(w.message, w.category, w.filename, w.lineno)


def _exit_code(args, exc):
    """Report ``exc`` and return its exit code; anything not an ``Exception`` (e.g.
    ``SystemExit``) propagates."""
    if not isinstance(exc, Exception):
        raise exc
    if isinstance(exc, InputError):
        what, code = "error", EXIT_INPUT
    elif isinstance(exc, AnalysisError):
        what, code = "analysis failed", EXIT_FAILED
    elif isinstance(exc, QSMAError):
        what, code = "error", EXIT_FAILED
    else:                               # a bug of ours, not a user mistake
        what, code = "internal error (please report it; --debug shows where)", EXIT_FAILED
    _report(args, exc, what)
    return code


def _report(args, exc, what):
    if getattr(args, "debug", False):
        traceback.print_exception(type(exc), exc, exc.__traceback__)
    text = str(exc) or type(exc).__name__
    print(f"qsma: {what}: {text}", file=sys.stderr)


if __name__ == "__main__":
    sys.exit(main())
