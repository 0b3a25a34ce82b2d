"""The open-loop pushes into the beams that sensing and planning start from (Sec. III-B):
the beams world alone, no CAN bus, so the estimator and the planner can be exercised (and
benchmarked) on the samples a closed-loop run would sense."""
from __future__ import annotations

import numpy as np

from hexhil.hil.world.beam_body import BeamParams
from hexhil.hil.world.beams import BeamsWorld


def push_samples(k1: float, k2: float, hb1_m: float, hb2_m: float, noise: float, sensing_ms: float,
                 seed: int, fx_n: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Sec. III-B: push with F_x into the beams; (poses, sensed forces) at 100 Hz for T_s."""
    world = BeamsWorld([BeamParams(k1, hb1_m), BeamParams(k2, hb2_m)], noise=noise, seed=seed)
    return world.sample_after_contact(sensing_ms * 1000, lambda: world.command(fx_n, 0.0, 0.0),
                                      10_000_000)


def start_after_delay(k1: float, k2: float, hb_m: float, delay_ms: float) -> tuple[float, float, float]:
    """The body pose after the sensory delay of a gentle (0.1 N) push from first contact."""
    world = BeamsWorld([BeamParams(k1, hb_m), BeamParams(k2, hb_m)])
    while world.first_contact_us is None or world.t_us - world.first_contact_us < delay_ms * 1000:
        world.command(0.1, 0.0, 0.0)
        world.step()
    return world.state.q()
