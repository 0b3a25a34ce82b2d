"""Seed 000 on the host: beam estimator (``estimator``), energy landscape (``landscape``),
Dijkstra planner (``planner``), control and the host nodes (``control``, ``nodes``), a whole
traversal (``beams_run``) and the force-sensing experiment (``force_sensing``). Importing it
registers the beams world's run, so ``hexhil run`` of a beams scenario and
``host_tools.Run`` traverse (host_tools/plugins.py)."""
from __future__ import annotations

from hil.run_result import RunResult
from hil.scenario import Scenario, WorldKind
from hil.seams import CanGateway, TraceRecorder
from host_tools import plugins


def _run(scenario: Scenario, seed: int, recorder: TraceRecorder | None,
         can_server: CanGateway | None, scene: bool, realtime: bool) -> RunResult:
    from host_tools.papers.beam_traversal import beams_run

    return beams_run.run_scenario(scenario, seed, recorder, can_server, scene, realtime)


plugins.register_stepped_run(WorldKind.BEAMS, _run)
