"""Shipped worlds: line descriptions built by name, some with parameters.

* ``straight_corridor`` — one long double track for the paper experiments (Paper A runs 203 m units at
  97.2 m/s, so the default line speed is 400 km/h = 111 m/s). Parameters: ``length_km`` (60),
  ``stations`` (3, evenly spaced, ends included), ``line_speed_kmh`` (400), ``platform_length_m`` (700:
  three 203 m units with gaps), ``overrun_m`` (500).
* ``y_junction`` — the junction planner's world (spec 004 §2.1, Fig. 2 as read there): ``entry3`` and
  ``entry2`` merge at switch ``sw1``; ``S4`` later ``entry1`` merges at ``sw2``; ``S5`` after ``sw2`` lies the
  planned coupling point ``F`` (a named point); then a platform (station ``platform``). ``S1`` is
  entry1's distance to sw2, ``S2``/``S3`` are entry2's/entry3's distances to sw1 (the trains' start points);
  each entry track starts ``approach_m`` (2 km) further upstream so trains can be inserted and brought up
  to speed. Defaults are Table 3 scenario 1: S1=400, S2=200, S3=160, S4=200, S5=200 m. Line speed 72 km/h
  (v_max 20 m/s); switch speeds 15 m/s normal / 10 m/s reverse over a ``turnout_length_m`` zone; throw time
  10 s (t_ls). Leg assignment (spec §6 #2 default): at sw1 entry2 normal, entry3 reverse; at sw2 the line
  from sw1 normal, entry1 reverse (``sw1_branch_leg``/``sw2_branch_leg`` swap them). The opposite track is
  built too: from the platform trains diverge at ``sw2_down`` and ``sw1_down`` back onto the entries.
  The main line is called ``trunk`` (its upstream part is entry2).
* ``chongqing_line3`` — Line 3 of Chongqing Rail Transit (package data ``chongqing_line3.yaml``; its header
  lists every reading and assumption). Parameters ``curve_allowance_kmh`` (50) and ``curve_allowance_m`` (300):
  no Line 3 curve or gradient list is public, but the data pack's running-time check says the published
  94 min end-to-end time implies "~10 min of curve/grade/turnout restrictions" on top of 30/45 s dwells.
  We place that allowance explicitly: one restriction of ``curve_allowance_m`` at ``curve_allowance_kmh`` in
  the middle of every inter-station section, both directions (50 km/h is the pack's curve rule
  ``v = 3.6·sqrt(R·0.6)`` for R ≈ 320 m). It is an *estimate standing in for unknown curves*, switchable:
  ``curve_allowance_kmh: 70`` (the line speed) removes it; replace it with real curve data when available.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import yaml

from railsim.errors import ConfigError

WORLD_DIR = Path(__file__).resolve().parent


def _straight_corridor(
    length_km: float, stations: int, line_speed_kmh: float, platform_length_m: float, overrun_m: float
) -> dict[str, Any]:
    n = stations
    return {
        "name": "straight_corridor",
        "description": f"Straight double-track corridor, {length_km:g} km, {n} stations, {line_speed_kmh:g} km/h.",
        "track": "double",
        "line_speed_kmh": line_speed_kmh,
        "platform_length_m": platform_length_m,
        "overrun_m": overrun_m,
        "main_line_id": "corridor",
        "stations": [
            {"id": f"s{i + 1}", "name": f"Station {i + 1}", "km": length_km * i / (n - 1), "turnback": i in (0, n - 1)}
            for i in range(n)
        ],
    }


def _y_junction(
    S1: float,
    S2: float,
    S3: float,
    S4: float,
    S5: float,
    approach_m: float,
    platform_offset_m: float,
    platform_length_m: float,
    line_speed_kmh: float,
    normal_speed_kmh: float,
    diverging_speed_kmh: float,
    throw_time_s: float,
    turnout_length_m: float,
    sw1_branch_leg: str,
    sw2_branch_leg: str,
) -> dict[str, Any]:
    sw1_km = (approach_m + S2) / 1000.0
    sw2_km = sw1_km + S4 / 1000.0
    f_km = sw2_km + S5 / 1000.0
    platform_km = f_km + (platform_offset_m + platform_length_m / 2) / 1000.0

    def origin(track_start_km: float) -> float:  # platform centre, 50 m clear of the track's end
        return round(track_start_km + (50.0 + platform_length_m / 2) / 1000.0, 6)

    def switch(sid: str) -> dict[str, Any]:
        return {
            "id": sid,
            "throw_time_s": throw_time_s,
            "diverging_speed_kmh": diverging_speed_kmh,
            "normal_speed_kmh": normal_speed_kmh,
        }

    return {
        "name": "y_junction",
        "description": (
            f"Three entry tracks merging through two switches (spec 004 Fig. 2): "
            f"S1={S1:g} S2={S2:g} S3={S3:g} S4={S4:g} S5={S5:g} m."
        ),
        "track": "double",
        "line_speed_kmh": line_speed_kmh,
        "platform_length_m": platform_length_m,
        "overrun_m": 100.0,
        "main_line_id": "trunk",
        "start_name": "entry2",
        "from_km": 0.0,
        # an origin station at the far end of each entry track (trains for the junction start from them,
        # usually already in motion close to the switches: scenario ``start: {before_switch, distance_m}``)
        "stations": [
            {"id": "entry2", "name": "Entry 2 origin", "km": origin(0.0)},
            {"id": "platform", "name": "Platform", "km": platform_km},
        ],
        "points": [{"id": "F", "line": "trunk", "km": f_km}],
        "branches": [
            {
                "id": "entry3",
                "name": "entry track 3",
                "joins": "trunk",
                "at_km": sw1_km,
                "side": "down",
                "leg": sw1_branch_leg,
                "turnout_length_m": turnout_length_m,
                "from_km": sw1_km - (S3 + approach_m) / 1000.0,
                "switches": {"up": switch("sw1"), "down": switch("sw1_down")},
                "stations": [
                    {"id": "entry3", "name": "Entry 3 origin", "km": origin(sw1_km - (S3 + approach_m) / 1000.0)}
                ],
            },
            {
                "id": "entry1",
                "name": "entry track 1",
                "joins": "trunk",
                "at_km": sw2_km,
                "side": "down",
                "leg": sw2_branch_leg,
                "turnout_length_m": turnout_length_m,
                "from_km": sw2_km - (S1 + approach_m) / 1000.0,
                "switches": {"up": switch("sw2"), "down": switch("sw2_down")},
                "stations": [
                    {"id": "entry1", "name": "Entry 1 origin", "km": origin(sw2_km - (S1 + approach_m) / 1000.0)}
                ],
            },
        ],
    }


def _chongqing_line3(curve_allowance_kmh: float, curve_allowance_m: float) -> dict[str, Any]:
    with (WORLD_DIR / "chongqing_line3.yaml").open(encoding="utf-8") as fh:
        raw = yaml.safe_load(fh)
    line_speed = float(raw["line_speed_kmh"])
    if curve_allowance_kmh >= line_speed:
        return raw
    half_km = curve_allowance_m / 2000.0
    limits = list(raw.get("speed_limits") or [])

    def add(line: str, stations: list[dict[str, Any]]) -> None:
        for a, b in zip(stations, stations[1:]):
            platform_km = float(raw.get("platform_length_m", 0.0)) / 2000.0
            free_km = (b["km"] - a["km"]) - 2 * platform_km
            if free_km < curve_allowance_m / 1000.0 + 0.1:  # no room between the platforms: leave it out
                continue
            mid = (a["km"] + b["km"]) / 2.0
            limits.append(
                {
                    "line": line,
                    "from_km": round(mid - half_km, 6),
                    "to_km": round(mid + half_km, 6),
                    "speed_kmh": curve_allowance_kmh,
                    "direction": "both",
                    "basis": "estimated: curve/grade allowance (world parameter curve_allowance_*)",
                }
            )

    add(raw.get("main_line_id", "main"), raw["stations"])
    for br in raw.get("branches", []):
        junction = [s for s in raw["stations"] if abs(s["km"] - br["at_km"]) < 0.3]
        add(br["id"], junction[:1] + list(br.get("stations", [])))
    raw["speed_limits"] = limits
    return raw


_PARAMS: dict[str, dict[str, Any]] = {
    "straight_corridor": {
        "length_km": 60.0,
        "stations": 3,
        "line_speed_kmh": 400.0,
        "platform_length_m": 700.0,
        "overrun_m": 500.0,
    },
    "y_junction": {
        "S1": 400.0,
        "S2": 200.0,
        "S3": 160.0,
        "S4": 200.0,
        "S5": 200.0,
        "approach_m": 2000.0,
        "platform_offset_m": 200.0,
        "platform_length_m": 400.0,
        "line_speed_kmh": 72.0,
        "normal_speed_kmh": 54.0,
        "diverging_speed_kmh": 36.0,
        "throw_time_s": 10.0,
        "turnout_length_m": 50.0,
        "sw1_branch_leg": "reverse",
        "sw2_branch_leg": "reverse",
    },
    "chongqing_line3": {"curve_allowance_kmh": 50.0, "curve_allowance_m": 300.0},
}
_BUILDERS: dict[str, Callable[..., dict[str, Any]]] = {
    "chongqing_line3": _chongqing_line3,
    "straight_corridor": _straight_corridor,
    "y_junction": _y_junction,
}


def shipped_worlds() -> list[str]:
    return sorted(_PARAMS)


def world_params(name: str) -> dict[str, Any]:
    """Default parameters of a shipped world."""
    return dict(_PARAMS[name])


def describe_world(name: str, **params: Any) -> tuple[dict[str, Any], str]:
    """Raw line-description mapping of a shipped world with ``params`` applied; returns (mapping, source)."""
    label = f"world {name}"
    defaults = _PARAMS[name]
    values = dict(defaults)
    for key, value in params.items():
        if key not in defaults:
            expected = ", ".join(defaults) if defaults else "none (this world has no parameters)"
            raise ConfigError(label, f"params.{key}", f"unknown parameter; expected one of {expected}")
        default = defaults[key]
        if isinstance(default, str):
            ok = value in ("normal", "reverse")
            what = "normal or reverse"
        elif isinstance(default, int):
            ok = isinstance(value, int) and not isinstance(value, bool) and value >= 2
            what = "an integer >= 2"
        else:
            ok = isinstance(value, (int, float)) and not isinstance(value, bool) and value > 0
            what = "a number > 0"
        if not ok:
            raise ConfigError(label, f"params.{key}", f"expected {what}, got {value!r}")
        values[key] = float(value) if isinstance(default, float) else value
    if name in _BUILDERS:
        return _BUILDERS[name](**values), label
    path = WORLD_DIR / f"{name}.yaml"
    with path.open(encoding="utf-8") as fh:
        return yaml.safe_load(fh), str(path)
