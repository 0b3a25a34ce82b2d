"""Limit-switch debouncing and the obstacle-overcoming rule of seed 003 (Eq. 5-7, Fig. 7).

A leg whose switch fired (a debounced press at any time since its last lift-off, or still
pressed at lift-off) takes the obstacle trajectory for its next step: l_k = 2 l_i (Eq. 6)
and h_k = H + 2 cm (Eq. 7). Parameters change only at lift-off, never mid-swing; a step
without contact returns the leg to l_i, h_i. MicroPython-compatible.
"""

OBSTACLE_CLEARANCE_M = 0.02  # Eq. 7: h_k = H + 2 cm
STEP_FACTOR = 2.0            # Eq. 6: l_k = 2 l_i


class Switches:
    """Six debounced switches: a level counts after holding ``samples`` cycles in a row."""

    def __init__(self, samples=2, n=6):
        self.samples = samples if samples > 0 else 1
        self.n = n
        self.state = 0         # debounced levels, bit i = leg i
        self._raw = 0
        self._count = [0] * n
        self.edges = 0         # debounced edges seen

    def update(self, raw_bits):
        """Take one sample of the raw levels; return the bits whose debounced level changed."""
        changed = 0
        for i in range(self.n):
            bit = 1 << i
            level = raw_bits & bit
            if level != (self._raw & bit):
                self._count[i] = 1
            elif self._count[i] < self.samples:
                self._count[i] += 1
            if self._count[i] >= self.samples and level != (self.state & bit):
                self.state ^= bit
                changed |= bit
                self.edges += 1
        self._raw = raw_bits
        return changed


class ObstacleRule:
    """Per-leg step parameters (Eq. 5): initial (l_i, h_i) or overcoming (l_k, h_k)."""

    def __init__(self, step_length_m, step_height_m, max_obstacle_height_m, enabled=True, n=6):
        self.enabled = enabled
        self.n = n
        self.set_initial(step_length_m, step_height_m, max_obstacle_height_m)
        self.contact = 0       # bit i: leg i touched something since its last lift-off
        self.overcoming = 0    # bit i: leg i's current step uses l_k, h_k
        self.l = [step_length_m] * n
        self.h = [step_height_m] * n
        self.changes = 0       # trajectory changes (either way)
        self.steps = 0         # lift-offs counted over all legs

    def set_initial(self, step_length_m, step_height_m, max_obstacle_height_m):
        self.l_i = step_length_m
        self.h_i = step_height_m
        self.l_k = STEP_FACTOR * step_length_m
        self.h_k = max_obstacle_height_m + OBSTACLE_CLEARANCE_M

    def touched(self, pressed_bits):
        """Note debounced presses (call every cycle with the debounced levels)."""
        self.contact |= pressed_bits

    def lift_off(self, leg, pressed_now):
        """Leg ``leg`` starts a step: latch its parameters. True if they changed."""
        bit = 1 << leg
        self.steps += 1
        hit = self.enabled and ((self.contact & bit) or pressed_now)
        self.contact &= ~bit
        was = self.overcoming & bit
        if hit:
            self.overcoming |= bit
            self.l[leg] = self.l_k
            self.h[leg] = self.h_k
        else:
            self.overcoming &= ~bit
            self.l[leg] = self.l_i
            self.h[leg] = self.h_i
        changed = bool(was) != bool(hit)
        if changed:
            self.changes += 1
        return changed
