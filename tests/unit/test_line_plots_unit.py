"""Line plots of a real run (mini Y line, start 07:30): train graph, speed, coupled gap, headways.

Here: the tests of it that start no process; the others are in ``tests/sumo/test_line_plots.py``.
"""

from __future__ import annotations

from railsim.report.plots import line, line_data


def test_spread_labels_keeps_order_and_spacing() -> None:
    ys = line.spread_labels([0.0, 0.05, 0.1, 3.0, 9.95, 10.0], 0.3, -0.5, 10.0)
    assert all(b - a >= 0.3 - 1e-12 for a, b in zip(ys, ys[1:]))
    assert ys[-1] <= 10.0 and ys[3] == 3.0
    assert line.station_label("Yudong (鱼洞)") == "Yudong"
    assert (
        line.station_label("Chongqing North Station South Square (重庆北站南广场)") == "Chongqing North Stn. South Sq."
    )
    long = line.station_label("Chongqing Technology and Business University")
    assert len(long) == line_data.NAME_CHARS and long.startswith("Chongqing Tech. & Business") and long.endswith("…")
