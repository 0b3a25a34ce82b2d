"""The host's CAN commands to the walking robot (``gait_command``), MicroPython-compatible.

stop/start, and a new gait, period, l_i and h_i, where 0 keeps the current value. A gait or
period change waits for the period to wrap (``firmware/gait.py``); new step parameters take
effect at each leg's next lift-off (Eq. 5-7), and so does a new walking direction
(``heading_command``). Other frames and undecodable ones (an enum outside its choices
included) are ignored.
"""
from protocol import can_frames as cf


class GaitCommands:
    """Applies ``gait_command`` frames to a controller; counts the ones it took."""

    def __init__(self, max_obstacle_height_m):
        self.max_obstacle_height_m = max_obstacle_height_m
        self.count = 0

    def take(self, ctl, now_us):
        """Drain the CAN receive queue at virtual time ``now_us``."""
        can = ctl.board.can
        while can.any():
            self.apply(ctl, can.recv(), now_us)

    def apply(self, ctl, frame, now_us):
        arb_id, data = frame
        try:
            name, sig = cf.decode(arb_id, data)
        except ValueError:
            return
        if name == "heading_command":
            self.count += 1
            ctl.set_direction(sig["direction_rad"])
            return
        if name != "gait_command" or sig["gait"] >= len(cf.GAIT_NAMES) \
                or sig["command"] >= len(cf.COMMAND_NAMES):
            return  # an enum outside its choices is undecodable too
        self.count += 1
        if sig["period_s"] > 0:
            ctl.gait.request(cf.GAIT_NAMES[sig["gait"]], sig["period_s"])
        if sig["step_length_m"] > 0 and sig["step_height_m"] > 0:
            ctl.rule.set_initial(sig["step_length_m"], sig["step_height_m"],
                                 self.max_obstacle_height_m)
        if sig["command"] == cf.COMMAND_STOP:
            ctl.stop_walking()
        elif sig["command"] == cf.COMMAND_START:
            ctl.start_walking(now_us)
