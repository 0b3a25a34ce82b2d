"""Paper experiments: sweeps of simulated runs, tables and plots (``hexhil experiment``)."""
