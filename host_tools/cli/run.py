"""``hexhil run SCENARIO.toml``: the firmware (or seed 000's host nodes) against the simulated
robot, in lockstep."""
from __future__ import annotations

import argparse
import sys

from hexhil.hil.canbus.socketcand import DEFAULT_PORT
from hexhil.hil.link.firmware_process import IN_PROCESS, RUNTIMES
from hexhil.hil.run_result import RunInterrupted
from hexhil import cli

LIVE_PORT = 8765  # Foxglove's default WebSocket port (host_tools/trace/live.py)


def add_flash_options(p: argparse.ArgumentParser) -> None:
    """--main, --fs and --fs-out: a MicroPython ELF's /flash
    (docs/micropython-on-the-chip.md)."""
    p.add_argument("--main", metavar="MAIN.py", help="with a MicroPython ELF as --firmware: "
                   "lay this file into its internal-flash filesystem as main.py, which it runs, "
                   "with the modules it imports from its package, compiled")
    p.add_argument("--fs", metavar="DIR", help="with a MicroPython ELF: lay DIR's files into "
                   "its /flash too")
    p.add_argument("--fs-out", metavar="DIR", help="with a MicroPython ELF: after the run, "
                   "write the files of its /flash into DIR (hexhil test and margin: into "
                   "DIR/<run>/, one folder a run)")


def add_masked_limit(p: argparse.ArgumentParser) -> None:
    """--masked-limit: an ELF's masked-spin limit (docs/elf-firmware.md)."""
    p.add_argument("--masked-limit", type=float, metavar="S", help="with an STM32F411 ELF: "
                   "the virtual seconds it may run with interrupts masked, or in a fault's "
                   "handler, before the run ends hung or crashed (default 0.5)")


def flash_files(args: argparse.Namespace):   # -> FlashFiles | None
    """The --main/--fs/--fs-out options as the API's ``flash_files``."""
    from pathlib import Path

    from hexhil.hil.mcu.flash_fs import FlashFiles
    given = (args.main, args.fs, getattr(args, "fs_out", None))
    if all(v is None for v in given):
        return None
    return FlashFiles(*(None if v is None else Path(v) for v in given))


def _run(args: argparse.Namespace) -> int:
    import hexhil.papers  # noqa: F401  (plugs the beams run and the navigators in)
    from hexhil import run_summary as run_mod

    cli.show_console(args.quiet)
    try:
        s, result = run_mod.run(args.scenario, args.duration, args.seed, args.python,
                                False if args.no_tactile else None, args.out,
                                args.can_server, args.can_wait, args.live, args.realtime,
                                args.navigator, args.model, args.firmware, args.gdb,
                                args.coverage, args.overwrite, cli.limits(args),
                                flash_files(args), args.coverage_libraries,
                                args.masked_limit)
    except RunInterrupted as exc:   # a beams run's trace holds no firmware link to replay
        replays = "" if exc.summary.get("world") == "beams" else " and replays"
        kept = (f"the trace {args.out} is kept{replays}" if args.out
                else "nothing was recorded (no --out)")
        sys.stderr.write(f"hexhil: interrupted at t={exc.result.sim_time_s:.3f} s: {kept}\n")
        if args.json and exc.summary:
            cli.emit_json(exc.summary)
        return cli.interrupted_status()
    if s.get("world") == "beams":
        what = "traversed" if s["traversed"] else ("flipped" if s["flipped"] else "stuck")
        print(f"{s['scenario']}: {s['strategy']}: {what} (mode {s['mode']}), energy "
              f"{s['energy_J'] * 1e3:.1f} mJ; {s['sim_time_s']:.1f} s simulated in "
              f"{s['wall_time_s']:.2f} s ({s['real_time_factor']}x)")
        if args.json:
            cli.emit_json(s)
        return 0
    for text in result.exceptions:
        print("firmware exception:\n" + text.rstrip())
    if result.unhandled_exceptions and result.stderr_tail:
        print("firmware stderr:\n" + result.stderr_tail)
    reported = s["state"] is not None or s["cycles"]   # a stats event (ours sends one)
    print(f"{s['scenario']}: {s['sim_time_s']:.1f} s simulated in {s['wall_time_s']:.2f} s "
          f"({s['real_time_factor']}x) under {s['firmware_runtime']}"
          + (f", {s['cycles']} cycles, {s['overruns']} overruns, state {s['state']}"
             if reported else "")
          + (f", stopped: {s['stop_reason']}" if s["stop_reason"] else ""))
    if s["faults"]:
        print("faults: " + ", ".join(f"{k} {v}" for k, v in s["faults"].items()))
    if s["no_servo_answered"]:
        print(s["no_servo_answered"])
    if s["violations"] and s["violations"]["total"]:
        print("master protocol violations: " + ", ".join(
            f"{k} {n}" for k, n in s["violations"]["counts"].items() if n))
    if s["console_dropped_bytes"]:
        from hexhil.hil.link.served_firmware import CONSOLE_TRACE_BYTES

        print(f"the firmware printed {s['console_dropped_bytes']:,} bytes more than the trace "
              f"keeps of its prints ({CONSOLE_TRACE_BYTES:,}): they were dropped")
    print(f"body: dx {s['body']['dx_m']:+.3f} m, dy {s['body']['dy_m']:+.3f} m, "
          f"dyaw {s['body']['dyaw_deg']:+.1f} deg; serial sha256 {s['serial_digest'][:16]}...")
    if "navigator" in s:
        n = s["navigator"]
        print(f"navigator {n['kind']}: stopped after step {n['stop_step']} of "
              f"{n['planned_steps']} planned (known path {n['known_steps']}); "
              f"{n['goal_dx_m']:+.3f} m short of the goal")
    ending = result.ending
    if not ending.completed:   # a verdict on the firmware: its lines here, the reason on stderr
        if ending.last_lines:
            print("the firmware's last lines:\n" + "\n".join(f"  {x}" for x in ending.last_lines))
        if s["trace"]:
            print(f"trace (kept up to then): {s['trace']}")
        print(f"hexhil: {ending.reason}", file=sys.stderr)
    if args.json:
        cli.emit_json(s)
    return 1 if s["unhandled_exceptions"] or not ending.completed else 0


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("run", help="run the firmware against the simulated robot",
                       description=__doc__)
    p.add_argument("scenario", help="scenario file (TOML), e.g. scenarios/flat-tripod.toml")
    p.add_argument("--duration", type=float, metavar="S", help="simulated seconds "
                   "(default: the scenario's duration_s, else 30)")
    p.add_argument("--seed", type=int, help="RNG seed (default: the scenario's, else 0)")
    p.add_argument("--runtime", "--python", dest="python", choices=(*RUNTIMES, IN_PROCESS),
                   help="firmware runtime (default: micropython, the reference); "
                        f"{IN_PROCESS} runs it in this process: same digest, faster")
    p.add_argument("--no-tactile", action="store_true",
                   help="turn the Eq. 5-7 obstacle rule off (the paper's baseline)")
    p.add_argument("--out", metavar="FILE.mcap", help="record the run to an MCAP trace "
                   "(with the 3D scene: robot, obstacles, switch plates, contact forces)")
    p.add_argument("--overwrite", action="store_true", help=cli.OVERWRITE_HELP)
    p.add_argument("--live", type=int, nargs="?", const=LIVE_PORT, metavar="PORT",
                   help="serve the trace's channels over the Foxglove WebSocket protocol on "
                        f"127.0.0.1 while the run goes (default port {LIVE_PORT}; 0 picks one)")
    p.add_argument("--realtime", action="store_true",
                   help="pace the run to the wall clock (to watch it live)")
    p.add_argument("--can-server", type=int, nargs="?", const=DEFAULT_PORT, metavar="PORT",
                   help="serve the simulated CAN bus over socketcand on 127.0.0.1 "
                        f"(default port {DEFAULT_PORT}; 0 picks a free one)")
    p.add_argument("--can-wait", type=int, default=0, metavar="N",
                   help="with --can-server: start only once N clients are attached")
    p.add_argument("--navigator", choices=("none", "model", "grnn"), default="none",
                   help="stop the walk where the goal (gait.distance_m) is predicted reached: "
                        "by Eq. 8-14 (model) or the GRNN (grnn, needs --model); none walks on")
    p.add_argument("--model", metavar="MODEL.pt", help="the GRNN for --navigator grnn "
                   "(hexhil grnn train)")
    p.add_argument("--firmware", metavar="PATH", help="run this firmware instead of ours: a "
                   "MicroPython main file (.py) on the virtual STM32F411 board (machine, time, "
                   "pyb in virtual time; docs/your-firmware.md), or an executable that speaks "
                   "the link, e.g. a C firmware built by `hexhil sdk build` (docs/c-firmware.md)")
    p.add_argument("--gdb", type=int, metavar="PORT", help="an ELF firmware waits for a GDB "
                   "client on 127.0.0.1:PORT before its first instruction; virtual time stands "
                   "still while it is halted (docs/elf-firmware.md)")
    p.add_argument("--coverage", metavar="FILE.info", help="an ELF firmware's line coverage "
                   "from its DWARF line table, as LCOV (genhtml, CI coverage reports)")
    cli.add_limits(p)
    add_flash_options(p)
    p.add_argument("--coverage-libraries", action="store_true", help="--coverage counts the "
                   "toolchain's libraries too (newlib, libgcc), not only the firmware's own "
                   "sources")
    add_masked_limit(p)
    p.add_argument("--json", action="store_true", help=cli.JSON_HELP)
    p.add_argument("--quiet", action="store_true", help="do not show the firmware's console "
                   "on stderr as it runs (its last lines stay in --json's console)")
    p.set_defaults(func=_run)
