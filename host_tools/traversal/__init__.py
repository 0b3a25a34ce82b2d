"""Seed 000 on the host: beam estimator, energy landscape, Dijkstra planner, control, closed loop."""
