"""Seed 003's GRNN positional-error predictor (Sec. 2.6, Fig. 8): per-step features from a
run (``features``), the dataset built from traces (``dataset``), the LSTM model
(``model``), its training (``train``) and evaluation on held-out terrains (``evaluate``).

Importing this package imports no torch: only ``model``, ``train`` and ``evaluate`` do.
"""
