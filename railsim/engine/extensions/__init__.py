"""Paper-specific behaviour that plugs into the step loop, selected by the scenario (never a branch in the loop)."""
