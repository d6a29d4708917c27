"""The run's progress bar (tqdm, on a terminal only): trips finished out of all trips, and the simulated time.

A run ends when every trip has finished, or at the horizon, so the bar counts finished trips (arrived or left
the line): it reaches 100 % when the last trip arrives, and the simulated time beside it (``t=720/1800 s``)
says how far the horizon is. It is redrawn every ``PROGRESS_EVERY_S`` of simulated time and once at the end.
"""

from __future__ import annotations

from typing import Any

PROGRESS_EVERY_S = 10.0  # progress bar update interval [simulated s]


class RunProgress:
    """Draws the bar for ``n_trips`` trips; :meth:`update` with the finished count, :meth:`close` at the end."""

    def __init__(self, name: str, n_trips: int, horizon_s: float, enabled: bool) -> None:
        self.horizon_s = float(horizon_s)
        self.last_s = -PROGRESS_EVERY_S
        self.bar: Any = None
        if enabled:
            from tqdm import tqdm

            self.bar = tqdm(total=n_trips, unit="trip", desc=name, leave=False)

    def update(self, t_s: float, n_finished: int, force: bool = False) -> None:
        """Redraw at simulated time ``t_s`` when ``PROGRESS_EVERY_S`` has passed (or ``force``)."""
        if self.bar is None or (not force and t_s - self.last_s < PROGRESS_EVERY_S):
            return
        self.last_s = t_s
        self.bar.n = n_finished
        self.bar.set_postfix_str(f"t={t_s:.0f}/{self.horizon_s:.0f} s", refresh=False)
        self.bar.refresh()

    def close(self, t_s: float, n_finished: int) -> None:
        if self.bar is not None:
            self.update(t_s, n_finished, force=True)
            self.bar.close()
