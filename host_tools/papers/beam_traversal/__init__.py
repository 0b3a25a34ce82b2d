"""Seed 000 on the host: beam estimator (``estimator``), energy landscape (``landscape``),
Dijkstra planner (``planner``), control and the host nodes (``control``, ``nodes``), a whole
traversal (``beams_run``) and the force-sensing experiment (``force_sensing``). Importing it
registers the beams world's run, so ``hexhil run`` of a beams scenario and
``host_tools.Run`` traverse (host_tools/plugins.py)."""
from __future__ import annotations

from hexhil.hil.scenario import WorldKind
from hexhil import plugins


def _load() -> plugins.SteppedRun:
    from hexhil.papers.beam_traversal import beams_run   # scipy, MuJoCo: when a run is made

    return beams_run.run_scenario


plugins.register_stepped_run(WorldKind.BEAMS, _load)
