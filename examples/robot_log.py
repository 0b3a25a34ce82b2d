"""A robot's logs through the Python API: a capture of its servo line and its CAN log
imported as one trace, the captured master checked, and the log replayed into our
firmware (what `hexhil trace import`, `conformance --capture` and `replay` do).

    python examples/robot_log.py LINE.sr CAN.asc OUT.mcap
"""
from __future__ import annotations

import sys

from hexhil.dynamixel.conformance.capture import check_capture
from hexhil.replay import replay_firmware
from hexhil.trace.import_logs import import_log


def main(capture: str, can_log: str, out: str) -> int:
    imported = import_log([capture, can_log], out, overwrite=True)
    for log in imported["logs"]:
        print(f"{log['kind']}: {log['input']}")
    check = check_capture(capture)
    print(f"master violations: {check['violations']['total']}, "
          f"framing errors: {check['line']['framing_errors']}")
    replay = replay_firmware(out)
    d = replay.divergence
    print("identical" if d is None else f"diverged at {d.t_s:.6f} s on {d.topic}: "
                                        f"{'; '.join((d.packets or {}).get('actual', []))}")
    return 0 if check["ok"] and d is None else 1


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:4]))
