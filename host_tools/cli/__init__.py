"""The ``hexhil`` command line.

Each subcommand lives in its own module of this package (``host_tools/cli``) and exposes
``register(subparsers)``; modules are imported only when their command runs, so a
slow import (MuJoCo, matplotlib) never taxes ``hexhil protocol decode``.
"""
from __future__ import annotations

import argparse
import importlib
import json
import logging
import os
import re
import signal
import sys
from typing import Any

from hexhil.lifecycle import ctrl_c_behind
from hexhil.protocol.errors import UserError

# command name -> (module in this package, one-line help)
COMMANDS: dict[str, tuple[str, str]] = {
    "demo": ("demo", "the whole stack once, end to end (what `make demo` runs)"),
    "protocol": ("protocol", "Dynamixel tools (decode Protocol 1.0 and 2.0)"),
    "bus": ("bus", "serve emulated Dynamixel servos (Protocol 1.0 or 2.0) on a pty or TCP port"),
    "conformance": ("conformance", "check any Dynamixel bus (Protocol 1.0 or 2.0) against the spec"),
    "run": ("run", "run the firmware against the simulated robot"),
    "experiment": ("experiment", "reproduce a paper's experiments"),
    "beams": ("beams", "force-sensing beam traversal (seed 000)"),
    "trace": ("trace", "inspect, export, recover and import MCAP traces"),
    "replay": ("replay", "replay a trace into the firmware or onto a CAN bus"),
    "estimate": ("estimate", "re-run the beam estimator on a trace's force frames"),
    "model": ("model", "the hexapod's robot description (URDF, MJCF)"),
    "render": ("render", "render a trace's ground truth to a video or PNG"),
    "grnn": ("grnn", "GRNN positional-error predictor (seed 003 Sec. 2.6)"),
    "test": ("test", "run expectation files against the firmware: pass/fail, JUnit XML"),
    "margin": ("margin", "sweep bus timing (Return Delay, adapter latency, bit errors, baud) until the expectations fail"),
    "fuzz": ("fuzz", "fuzz the firmware through its bus: faults in virtual time, shrunk reproducers"),
    "sdk": ("sdk", "build a C firmware against the STM32Cube-style C SDK"),
}


# Exit statuses are the command line's alone; the library raises, the shell maps: a
# UserError of any kind (protocol/errors.py: BadValue, BadFile) is bad input, status 2.
EXIT_BAD_INPUT = 2

# every --json says this, whatever the command: scripts may rely on the last line
JSON_HELP = "end with the result as one JSON object, the last line of stdout (for scripts)"
OVERWRITE_HELP = "replace a trace file that already exists (without it, an existing file is refused)"


def actions(sub: argparse._SubParsersAction, name: str, help: str, metavar: str = "ACTION",
            description: str | None = None) -> argparse._SubParsersAction:
    """``hexhil NAME ACTION ...``: a command whose action is required (without one, a one-line
    error names it)."""
    p = sub.add_parser(name, help=help, description=description)
    return p.add_subparsers(dest=f"{name}_action", metavar=metavar, parser_class=type(p),
                            required=True)


# The library's errors name API parameters (protocol/errors.py ``params``); a user of the
# CLI typed these flags for them.
FLAGS = {"python": "--runtime", "runtime": "--runtime", "firmware": "--firmware", "duration_s": "--duration",
         "can_server_port": "--can-server", "can_wait_clients": "--can-wait",
         "live_port": "--live", "start_s": "--start", "end_s": "--end", "rate": "--rate",
         "spec": "--can", "bus_args": "--can-arg", "out": "--out", "out_dir": "--out",
         "fps": "--fps", "at_s": "--at", "workers": "--workers", "trace": "--trace",
         "terrains": "--terrains", "distance_m": "--distance", "epochs": "--epochs",
         "world": "--world", "model_path": "--model", "topics": "--topics",
         "gdb_port": "--gdb", "coverage": "--coverage", "bare": "--bare", "target": "--target",
         "seed": "--seed", "tactile": "--no-tactile", "overwrite": "--overwrite",
         "keep_dir": "--keep-traces", "map_path": "--map", "scenario": "--scenario",
         "kind": "--as", "max_wall_s": "--max-wall", "max_memory_mb": "--max-memory",
         "width": "--width", "height": "--height", "png": "--png", "junit": "--junit",
         "main": "--main", "fs": "--fs", "fs_out": "--fs-out",
         "coverage_libraries": "--coverage-libraries", "main_file": "--in-process",
         "runs": "--runs", "time_s": "--time", "jobs": "--jobs", "kinds": "--kinds",
         "window_s": "--window", "masked_limit_s": "--masked-limit"}


def flag_message(exc: UserError) -> str:
    """``exc``'s message with the API parameters it names written as the flags that set them:
    each one's first mention (a later one is the plain word: "a C firmware")."""
    msg = str(exc)
    for param in exc.params:
        if param in FLAGS:
            msg = re.sub(rf"(?<![\w\-\[.'])({re.escape(param)})(?![\w\]])",
                         FLAGS[param], msg, count=1)
    return msg


def add_limits(p: argparse.ArgumentParser) -> None:
    """``--max-wall`` and ``--max-memory``: a run's caps (hil/run/limits.py)."""
    from hexhil.hil.run.limits import DEFAULT_MEMORY_MB, WALL_BASE_S, WALL_PER_SIM_S

    p.add_argument("--max-wall", type=float, metavar="S", help="end a run that takes more "
                   f"than S wall seconds (default {WALL_BASE_S:g} + {WALL_PER_SIM_S:g} per "
                   "simulated second): a verdict, ending 'limit'")
    p.add_argument("--max-memory", type=float, metavar="MB", default=DEFAULT_MEMORY_MB,
                   help="end a run once hexhil and its firmware hold more than MB MiB "
                        f"(default {DEFAULT_MEMORY_MB:g}): a verdict, ending 'limit'")


def limits(args: argparse.Namespace) -> Any:
    """The ``RunLimits`` of ``--max-wall`` and ``--max-memory``."""
    from hexhil.hil.run.limits import RunLimits

    return RunLimits(args.max_wall, args.max_memory)


class _Parser(argparse.ArgumentParser):
    """argparse that raises UserError instead of printing usage and exiting."""

    def error(self, message: str) -> None:  # type: ignore[override]
        raise UserError(f"{message} (see '{self.prog} --help')")


class _Version(argparse.Action):
    """``hexhil --version``: the package's version and which compiled cores this install has."""

    def __init__(self, option_strings: list[str], dest: str, **kwargs: Any) -> None:
        super().__init__(option_strings, dest, nargs=0, help="print the version and which "
                         "compiled cores are built, then exit")

    def __call__(self, parser: argparse.ArgumentParser, *_: Any) -> None:
        from importlib.metadata import version

        from hexhil.hil.native import compiled

        lines = [f"hexhil {version('hexhil')}"]
        lines += [f"  {name}: {state}" for name, state in compiled().items()]
        sys.stdout.write("\n".join(lines) + "\n")
        parser.exit(0)


def build_parser(argv: list[str]) -> argparse.ArgumentParser:
    parser = _Parser(prog="hexhil", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action=_Version)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    wanted = argv[0] if argv and argv[0] in COMMANDS else None
    for name, (module, help_text) in COMMANDS.items():
        if wanted is not None and name != wanted:
            sub.add_parser(name, help=help_text)
            continue
        try:
            mod = importlib.import_module(f"hexhil.cli.{module}")
        except ModuleNotFoundError as exc:
            if exc.name != f"hexhil.cli.{module}":
                raise
            continue  # command not built yet: leave it out of the listing
        mod.register(sub)
    _describe(parser)
    return parser


def _describe(parser: argparse.ArgumentParser) -> None:
    """Every parser's --help says what it does: its description (docstrings here are
    reStructuredText: ``x`` shows as x), else the line its parent's listing gives it."""
    if parser.description:
        parser.description = parser.description.replace("``", "")
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for listed in action._choices_actions:
                child = action.choices[listed.dest]
                child.description = child.description or listed.help
                _describe(child)


def emit_json(obj: dict[str, Any]) -> None:
    """Print one JSON object as the last line of stdout (the ``--json`` contract)."""
    sys.stdout.write(json.dumps(obj, sort_keys=True) + "\n")
    sys.stdout.flush()


def flush_print(line: str) -> None:
    """One line on stdout at once: an address a script waits for (a pty, a port)."""
    sys.stdout.write(line + "\n")
    sys.stdout.flush()


class _LibraryLog(logging.Handler):
    """What the library logs for the user (``logging``, never ``print``): INFO lines on
    stdout as they come (the addresses ``hexhil run`` serves), warnings on stderr."""

    def emit(self, record: logging.LogRecord) -> None:
        line = self.format(record)
        if record.levelno >= logging.WARNING:
            sys.stderr.write(f"warning: {line}\n")
        else:
            flush_print(line)


def _show_library_log() -> None:
    """Route the project's loggers to the terminal, once per process."""
    logger = logging.getLogger("hexhil")
    if not any(isinstance(h, _LibraryLog) for h in logger.handlers):
        handler = _LibraryLog()
        # the firmware's console has its own handler (show_console), or none when quiet
        handler.addFilter(lambda record: not record.name.startswith("hexhil.console"))
        logger.addHandler(handler)
        logger.setLevel(logging.INFO)


class _ConsoleLog(logging.Handler):
    """The firmware's console as it prints (hil/link/server.py ``CONSOLE_LOG``): each
    line on stderr after its virtual time."""

    def emit(self, record: logging.LogRecord) -> None:
        sys.stderr.write(f"[{getattr(record, 't_s', 0.0):10.6f} s] {record.getMessage()}\n")
        sys.stderr.flush()


def show_console(quiet: bool) -> None:
    """The firmware's console live on stderr, unless ``quiet`` (once per process)."""
    from hexhil.hil.link.server import CONSOLE_LOG as logger
    logger.propagate = False
    for h in [h for h in logger.handlers if isinstance(h, _ConsoleLog)]:
        logger.removeHandler(h)
    if not quiet:
        logger.addHandler(_ConsoleLog())
        logger.setLevel(logging.INFO)


def emit(args: Any, obj: dict[str, Any], text: str) -> None:
    """A command's result: ``obj`` as JSON with ``--json``, else ``text`` for a person."""
    if getattr(args, "json", False):
        emit_json(obj)
    else:
        print(text)


class ProgressBar:
    """The library's ``Progress`` callback (host_tools/progress.py) drawn as a tqdm bar on
    stderr, one bar per stage (a new ``desc`` or a restart at 0 closes the last one)."""

    def __init__(self, unit: str) -> None:
        self.unit = unit
        self._bar: Any = None
        self._desc = ""

    def __call__(self, desc: str, done: int, total: int, note: str = "") -> None:
        from tqdm import tqdm

        if self._bar is None or done == 0 or desc != self._desc:
            self.close()
            self._bar = tqdm(total=total, desc=desc, unit=self.unit, file=sys.stderr,
                             dynamic_ncols=True)
            self._desc = desc
        self._bar.update(done - self._bar.n)
        if note:
            self._bar.set_postfix_str(note)
        if done >= total:
            self.close()

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None


# the signal that interrupted this command (the console script's handlers), None: none yet
_signalled: list[signal.Signals | None] = [None]


def _terminated(signum: int, frame: Any) -> None:
    """SIGTERM ends a command as Ctrl-C does: ``finally`` blocks finish the trace files."""
    _signalled[0] = signal.Signals(signum)
    raise KeyboardInterrupt


def interrupted_status() -> int:
    """The exit status of a command a signal ended: 128 + its number, 130 for Ctrl-C
    (SIGINT), 143 for SIGTERM (systemd's, a CI runner's, ``docker stop``'s)."""
    return 128 + int(_signalled[0] or signal.SIGINT)


def main(argv: list[str] | None = None) -> int:
    if argv is None:  # the console script, not a test calling main() in-process
        # numpy's matrices here are small: OpenBLAS's worker threads would only spin on
        # start-up, on a core the emulated chip could use (set the variable to choose)
        os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
        signal.signal(signal.SIGTERM, _terminated)
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:   # not ignored
            signal.signal(signal.SIGINT, _terminated)
        status = _main(sys.argv[1:])
        if _signalled[0] is not None and status == interrupted_status():
            # Interrupted: every file is finished, and the interpreter's own teardown
            # (MuJoCo's, about 0.7 s on a loaded machine) is skipped so the signal is
            # acted on within a second.
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(status)
        return status
    return _main(argv)


def _main(argv: list[str]) -> int:
    _show_library_log()
    try:
        parser = build_parser(argv)
        args = parser.parse_args(argv)
        if not getattr(args, "func", None):
            parser.print_help()
            return 2
        return int(args.func(args) or 0)
    except UserError as exc:
        sys.stderr.write(f"hexhil: {flag_message(exc)}\n")
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        return interrupted_status()
    except ImportError as exc:   # Ctrl-C inside a C extension's initialisation (MuJoCo's)
        if ctrl_c_behind(exc) is not None:
            return interrupted_status()
        raise
    except BrokenPipeError:
        return 0

