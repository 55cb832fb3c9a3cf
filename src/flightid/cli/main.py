"""``flightid`` console entry point.

Each sub-command lives in its own module ``flightid.cli.<name>`` exposing
``register(subparsers)``, which adds its parser and sets ``func(args) -> int``.

Every failure ends in one line on stderr and a non-zero exit status:

    flightid: error: <what went wrong>                         exit 1 (bad input, I/O)
    flightid: error: internal error: <type>: <message> (run with --debug for the traceback)
                                                               exit 1 (a bug)
    flightid: interrupted                                      exit 130 (Ctrl-C, SIGINT)
    flightid: terminated                                       exit 143 (SIGTERM)

SIGTERM (``kill PID``, a job scheduler's stop) is handled like Ctrl-C: the command stops
where it is, its result-folder lock and temporary files are removed, nothing half written
stays.

Every warning is one line on stderr: flightid's own (``flightid.errors.FlightIdWarning``,
e.g. a model that runs in pure Python, a parallel kernel numba could not compile) as
``flightid: warning: <message>``, any other (numpy's, numba's) as
``flightid: warning: <message> (<category>)``, without the library's file path and source.

``--debug`` (before or after the command) adds the Python traceback.

The console script (``console_main``) ends the process as soon as the command is done: it
flushes stdout and stderr, runs the ``atexit`` handlers (logging's flush, multiprocessing's
and Dask's clean-up) and leaves with ``os._exit``, skipping the interpreter's teardown of every
loaded module (about 0.1 s after an estimation). Every file, lock and temporary folder of a
command is closed or removed in its own ``finally`` before that; numba writes its cache
files when it compiles. ``FLIGHTID_NORMAL_EXIT=1`` restores the interpreter's ordinary exit
(for debugging or profiling what runs at exit). ``main`` itself, called from Python, only
returns the exit status.
"""

from __future__ import annotations

import argparse
import atexit
import contextlib
import importlib
import os
import signal
import sys
import threading
import traceback
import warnings

from flightid._version import __version__
from flightid.errors import FlightIdWarning, error_line

# Sub-command modules, in the order they appear in --help.
SUBCOMMAND_MODULES = (
    "batch",
    "design",
    "example_logs",
    "export",
    "inspect",
    "paper",
    "regress",
    "run",
    "validate",
)
EXIT_ERROR = 1
EXIT_INTERRUPTED = 130  # 128 + SIGINT, as shells report it
EXIT_TERMINATED = 143  # 128 + SIGTERM
DEBUG_HELP = "show the Python traceback of a failure"


def _add_debug(parser: argparse.ArgumentParser) -> None:
    """``--debug`` on every sub-command parser too (the default stays the top level's)."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                if not any("--debug" in a.option_strings for a in sub._actions):
                    sub.add_argument(
                        "--debug", action="store_true", default=argparse.SUPPRESS, help=DEBUG_HELP
                    )
                _add_debug(sub)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="flightid",
        description="Airplane parameter estimation from flight data (NASA RP-1153 methodology).",
    )
    parser.add_argument("--version", action="version", version=f"flightid {__version__}")
    parser.add_argument("--debug", action="store_true", help=DEBUG_HELP)
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in SUBCOMMAND_MODULES:
        try:
            module = importlib.import_module(f"flightid.cli.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"flightid.cli.{name}":
                continue  # sub-command not built yet
            raise
        module.register(subparsers)
    _add_debug(parser)
    return parser


class Terminated(KeyboardInterrupt):
    """SIGTERM arrived: raised where the program was, so that every clean-up Ctrl-C runs
    (``finally`` blocks, the result folder's lock and temporary folder) runs for it too."""


def _raise_terminated(signum, frame) -> None:
    raise Terminated


@contextlib.contextmanager
def _sigterm_as_interrupt():
    """SIGTERM raises ``Terminated`` while the command runs (only from the main thread, and
    only where SIGTERM had its default action: a handler the caller installed is kept)."""
    installed = False
    if threading.current_thread() is threading.main_thread():
        with contextlib.suppress(ValueError, OSError):
            if signal.getsignal(signal.SIGTERM) == signal.SIG_DFL:
                signal.signal(signal.SIGTERM, _raise_terminated)
                installed = True
    try:
        yield
    finally:
        if installed:
            signal.signal(signal.SIGTERM, signal.SIG_DFL)


def warning_line(message: Warning | str, category: type[Warning]) -> str:
    """One line for a warning: ``flightid: warning: <message>`` for a ``FlightIdWarning``,
    ``flightid: warning: <message> (<category>)`` for any other."""
    text = " ".join(str(message).split())
    if issubclass(category, FlightIdWarning):
        return f"flightid: warning: {text}"
    return f"flightid: warning: {text} ({category.__name__})"


def _one_line_warnings():
    """``warnings.showwarning`` that prints every warning as one line (``warning_line``)."""

    def showwarning(message, category, filename, lineno, file=None, line=None):
        print(warning_line(message, category), file=sys.stderr if file is None else file)

    return showwarning


def main(argv: list[str] | None = None) -> int:
    with _sigterm_as_interrupt(), warnings.catch_warnings():
        warnings.showwarning = _one_line_warnings()
        return _main(argv)


def _main(argv: list[str] | None) -> int:
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
    except KeyboardInterrupt:
        print("flightid: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    debug = bool(getattr(args, "debug", False))
    try:
        return int(args.func(args) or 0)
    except Terminated:
        if debug:
            traceback.print_exc()
        print("flightid: terminated", file=sys.stderr)
        return EXIT_TERMINATED
    except KeyboardInterrupt:
        if debug:
            traceback.print_exc()
        print("flightid: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        # the reader of stdout went away (e.g. `| head`): nothing more to say to it; point
        # stdout at /dev/null so that the flush at exit does not fail again
        with contextlib.suppress(OSError, ValueError):
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        return EXIT_ERROR
    except Exception as exc:  # every failure: one line, the traceback only with --debug
        if debug:
            traceback.print_exc()
        print(error_line(exc), file=sys.stderr)
        return EXIT_ERROR


def console_main() -> None:
    """The ``flightid`` console script: ``main()``, then the fast exit (module docstring)."""
    try:
        status = main()
    except SystemExit as exc:  # argparse: --help, --version, a bad command line
        status = exc.code
    exit_now(status)


def _exit_status(status: object) -> int:
    """The process exit status of a ``SystemExit`` code (None: 0; a message: printed, 1)."""
    if status is None:
        return 0
    if isinstance(status, int):
        return status
    print(status, file=sys.stderr)
    return EXIT_ERROR


def _flush_standard_streams() -> bool:
    """Flush stdout and stderr; False when the reader of stdout went away (its pipe closed),
    stdout then pointed at /dev/null so that nothing tries to write there again."""
    reader_present = True
    for stream in (sys.stdout, sys.stderr, sys.__stdout__, sys.__stderr__):
        if stream is None:
            continue
        try:
            stream.flush()
        except BrokenPipeError:
            reader_present = False
            with contextlib.suppress(OSError, ValueError):
                devnull = os.open(os.devnull, os.O_WRONLY)
                os.dup2(devnull, stream.fileno())
        except (OSError, ValueError):  # a closed or detached stream: nothing to flush
            pass
    return reader_present


def exit_now(status: object) -> None:
    """End the process with ``status``: flush stdout and stderr, run the ``atexit``
    handlers, flush again, ``os._exit`` (the interpreter's teardown of the loaded modules is
    skipped). The interpreter's ordinary exit (``sys.exit``) where ``FLIGHTID_NORMAL_EXIT``
    is set to anything but ``0``, or while another non-daemon thread runs (the ordinary exit
    waits for it)."""
    code = _exit_status(status)
    others = [t for t in threading.enumerate() if t is not threading.main_thread() and not t.daemon]
    if os.environ.get("FLIGHTID_NORMAL_EXIT", "0") not in ("", "0") or others:
        sys.exit(code)
    if not _flush_standard_streams() and code == 0:
        code = EXIT_ERROR  # the answer did not reach its reader (as a BrokenPipeError above)
    atexit._run_exitfuncs()
    _flush_standard_streams()
    os._exit(code)


if __name__ == "__main__":
    console_main()
