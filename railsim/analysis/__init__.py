"""Analyses of finished runs: line sections and capacity (UIC 406), and one module per paper family's metrics.

Everything here reads run folders (``trips.csv``, ``trace.csv`` …) and never imports the engine.
"""
