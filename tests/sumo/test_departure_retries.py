"""A held departure is retried every second; the retries are summarised, not written one row each.

On a single-track line (built here with netconvert) two trains are due at the same moment from opposite ends: the
second waits at its platform until the first has left the section, about three minutes. Each retry used to be a
``departure_retry`` row (one run on an OSM city extract wrote 165,521 of them, 6 MB); now the first retry is one
row and the rest are counted in one ``departure_retries`` event when the train is inserted.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from tests.helpers import read_csv
from tests.sumo.test_external_net import _service
from tests.sumo.test_single_track import _run, build_single_line


def test_retries_of_a_held_departure_are_one_row_and_a_count(tmp_path: Path) -> None:
    net, stops = build_single_line(tmp_path)
    services = [_service("east", "aston", "bury", 0), _service("west", "bury", "aston", 0)]
    out, s, _ = _run(tmp_path, "single_line", net, stops, services)
    assert s["n_arrived"] == 2
    events = read_csv(out / "events.csv")
    retries = [e for e in events if e["kind"] == "departure_retry"]
    assert len(retries) == 1 and retries[0]["subject"] == "west.000"
    (summary,) = [e for e in events if e["kind"] == "departure_retries"]
    inserted = next(float(e["t_s"]) for e in events if e["kind"] == "train_inserted" and e["subject"] == "west.000")
    assert summary["subject"] == "west.000" and float(summary["t_s"]) == inserted
    # one retry a second from the first retry to the insertion
    assert yaml.safe_load(summary["detail"])["count"] == pytest.approx(inserted - float(retries[0]["t_s"]) + 1, abs=1)
