"""Recording: per-step samples, trip/stop/formation statistics and atomic output files.

Fed snapshots by the engine; imports nothing above it (docs/architecture.md).
"""
