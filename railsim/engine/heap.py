"""The garbage collector and the step loop: what the set-up built is not scanned again during the run.

CPython's cyclic collector scans the whole long-lived heap on every full (generation-2) collection, and starts
one whenever the long-lived objects have grown by a quarter since the last. A run's set-up builds a large heap
that lives as long as the run: trips and their stops, free-run plans, route views, controllers, the network
graph — it grows with the number of trains. During the run, the objects that survive a while (in-flight radio
messages, recorded samples) keep triggering full collections, and each one walked the whole set-up again: at
3,000 simultaneous trains these collections cost ~18 µs per train-step (a fifth of the step), and they made the
per-train cost grow with the number of trains (``benchmarks/scale.py``).

:func:`setup_frozen` collects once, then moves every object alive at the start of the loop to the collector's
permanent generation (:func:`gc.freeze`) for the run and back at its end (:func:`gc.unfreeze`). Reference
counting still frees every frozen object that is dropped; only a reference cycle among them would wait until the
end of the run. The collector never changes what the program computes, so outputs are unchanged (golden test).
"""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager


@contextmanager
def setup_frozen() -> Iterator[None]:
    """Freeze the heap as it is (after one full collection) for the ``with`` block; unfreeze after it."""
    gc.collect()
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()
