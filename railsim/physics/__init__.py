"""Physics: what a train *is* and how it moves, independent of any simulation.

Vehicle parameters (:mod:`.vehicle`), the longitudinal point-mass plant with envelopes, jerk and lag
(:mod:`.dynamics`), Paper B's carriage-by-carriage plant (:mod:`.multipoint`), Paper D's monorail drive
(:mod:`.monorail`) and physical constants (:mod:`.units`). The lowest railsim layer: it imports only
:mod:`railsim.errors`, and it is the only railsim code that :mod:`controllers` may import (docs/architecture.md).
"""
