"""What the recorder logs of the simulated robot: body pose, joints, the 3D scene, servos.

The lockstep simulator (hil/run/lockstep.py) and the real-time rig (hil/run/realtime_rig.py) sample on
their own clocks and call this for what to write, so a trace of either has the same topics.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any, Sequence

from hexhil.hil.seams import FirmwareWorld, SteppedWorld, TraceRecorder

if TYPE_CHECKING:
    from hexhil.hil.servobus.line import Bus


class GroundTruth:
    """``world_sample(t_us)``: pose, joints and (with ``scene``) the 3D scene's changed
    shapes, frames and forces; ``servo_sample(t_us)``: the servos' states."""

    def __init__(self, world: FirmwareWorld | SteppedWorld | None, servos: Sequence[Any],
                 recorder: TraceRecorder, scene: bool, bus: Bus | None = None) -> None:
        self.world, self.servos, self.recorder, self.scene = world, servos, recorder, scene
        self.bus = bus   # the servos' line: its compiled bank samples them in one call
        self._shapes: dict[str, Any] = {}  # the geometry sent, by shape id
        self._last_shapes: list[Any] = []  # the world's last answer (mostly the same objects)

    def world_sample(self, t: int) -> None:
        w, rec = self.world, self.recorder
        p = w.body_pose()
        rec.body_pose(t, (p.x_m, p.y_m, p.z_m), p.quat_wxyz)
        rec.joints(t, w.joint_names(), w.joint_positions().tolist(),
                   w.joint_velocities().tolist(), w.joint_efforts_nm().tolist())
        self.draw(t)

    def draw(self, t: int) -> None:
        """The world's 3D scene: the shapes that changed, then its frames and forces."""
        if not self.scene:
            return
        w, rec = self.world, self.recorder
        shapes = w.scene_shapes()
        if shapes != self._last_shapes:  # fast: unchanged shapes are the same objects
            self._last_shapes = shapes
            changed = [s for s in shapes if self._shapes.get(s.id) != s]
            if changed:
                self._shapes.update((s.id, s) for s in changed)
                rec.scene(t, changed)
        rec.scene_frames(t, w.scene_frames())
        rec.scene_forces(t, w.scene_arrows())

    def servo_sample(self, t: int) -> None:
        bank = self.bus.servo_bank if self.bus is not None else None
        rows = bank.state_rows(self.servos) if bank is not None else None
        self.recorder.servo_state(t, rows if rows is not None else
                                  [s.state_row() for s in self.servos])
