"""A host node of your own beside the firmware, through hexhil's public API alone
(docs/api.md): it logs the body's height every 100 ms and, one second in, tells the firmware
to crab-walk 30 degrees to the left with a ``heading_command`` CAN frame. The run is recorded,
the trace read back, and the walk's figures printed.

    python examples/host_node.py [OUT.mcap]
"""
from __future__ import annotations

import math
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import hexhil as hx  # noqa: E402  (the public API; the line above finds it from a clone)

SCENARIO = Path(__file__).resolve().parents[1] / "scenarios" / "flat-tripod.toml"
DURATION_S = 6.0
TURN_AT_US = 1_000_000
HEADING_RAD = math.radians(30.0)


class HeightLogger:
    """A ``hx.HostNode``: ticked every ``period_us`` of virtual time."""

    period_us = 100_000

    def __init__(self, run: hx.Run) -> None:
        self.world = run.world
        self.port = run.can_endpoint()
        self.heights_m: list[tuple[int, float]] = []
        self.sent = False

    def tick(self, t_us: int) -> None:
        self.heights_m.append((t_us, self.world.body_pose().z_m))
        if t_us >= TURN_AT_US and not self.sent:
            self.port.send(hx.can_message("heading_command", direction_rad=HEADING_RAD))
            self.sent = True


def main(out: Path) -> None:
    scenario = hx.load_scenario(SCENARIO)
    with hx.Run(scenario, runtime=hx.Runtime.CPYTHON_INPROCESS, duration_s=DURATION_S,
                trace=out) as run:
        logger = HeightLogger(run)
        run.add_node(logger)
        result = run.run()
    if result.ending.kind is not hx.Ending.COMPLETED:   # a FirmwareEnding: crashed, hung, ...
        raise SystemExit(f"the run failed: {result.ending.reason}")

    heading_frames, poses = 0, []
    with hx.open_trace(out) as trace:
        for msg, value in trace.decoded(["/can/raw", "/body"]):
            if msg.topic == "/can/raw":
                heading_frames += value["arbitration_id"] == hx.can_frames.ID_HEADING_COMMAND
            else:
                poses.append((msg.log_time_ns * 1e-9, value["translation"]))
        recorded, seed = hx.scenario_of_trace(trace.metadata(), str(out))
    heights = [z for _, z in logger.heights_m]
    (t0, p0), (t1, p1) = poses[0], poses[-1]
    travel_deg = math.degrees(math.atan2(p1["y"] - p0["y"], p1["x"] - p0["x"]))
    print(f"scenario {recorded.name} (seed {seed}) under {result.runtime}: {result.sim_time_s:.1f} s, "
          f"{result.cycles} cycles, state {result.firmware.state}, firmware "
          f"{result.ending.kind.value}")
    print(f"body height: {len(heights)} samples, mean {sum(heights) / len(heights) * 1e3:.1f} "
          f"mm, min {min(heights) * 1e3:.1f} mm, max {max(heights) * 1e3:.1f} mm")
    print(f"trace: {len(poses)} body poses, {heading_frames} heading_command frame(s)")
    print(f"walked {math.hypot(p1['x'] - p0['x'], p1['y'] - p0['y']):.3f} m "
          f"at {travel_deg:+.1f} deg from x in {t1 - t0:.1f} s")


if __name__ == "__main__":
    if len(sys.argv) > 1:
        main(Path(sys.argv[1]))
    else:
        with tempfile.TemporaryDirectory() as tmp:
            main(Path(tmp) / "host_node.mcap")
