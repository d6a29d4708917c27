"""The same trips driven by SUMO alone: the reference for what our controlled loop costs.

Every trip of a scenario is inserted at its planned departure on its route with its station stops, but SUMO's
own car-following model (Krauss, with the vehicle's acceleration and service braking) drives it — no
controllers, no plant, no event layer, no formations. Used by ``benchmarks/engine.py`` to report the overhead
ratio ``wall(railsim) / wall(SUMO alone)`` on the same net. Not a safe operating mode: SUMO's unsignalled
junctions do not interlock (see the SUMO findings), so collisions in this mode are expected and only counted.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from railsim.engine.sumo import StopSpec, SumoBridge, SumoConfig, VTypeSpec
from railsim.engine.trips import make_stops


def run_sumo_only(
    scenario: Any,
    on_step: Callable[[float], None] | None = None,
    before_step: Callable[[SumoBridge], None] | None = None,
) -> dict[str, Any]:
    """Drive every trip of ``scenario`` with SUMO alone (see the module docstring); return wall time and counts.

    A trip that starts in motion (``services[].start``) is inserted like the engine inserts it: on its route
    trimmed to the edge that holds its start chainage, at its start speed, with the stops still ahead of it.
    ``on_step(t)`` is called before every SUMO step (``benchmarks/scale.py`` takes its per-step clock there), then
    ``before_step(bridge)`` (``benchmarks/io_floor.py`` adds the engine's traffic with SUMO there).
    """
    from network.world import load_world, sumo_args
    from railsim import scenario as scn_mod

    sim = scenario.simulation
    bundle = load_world(scenario.world, scenario.source)
    if bundle.station_aliases:  # an external net: stations named by name or stop id -> station ids
        scenario = scn_mod.with_station_ids(scenario, bundle)
    trips = []
    for svc in scenario.services:
        route = bundle.route_between(svc.from_station, svc.to_station, tuple(svc.via), svc.platforms)
        veh = scenario.vehicles[svc.vehicle]
        stops = make_stops(
            route,
            veh.length_m,
            tuple(svc.skip),
            svc.dwell_default_s,
            dict(svc.dwell_by_station),
            svc.from_station,
            svc.to_station,
        )
        start_m = stops[0].mark_m + float(svc.start_offset_m)
        if svc.start_offset_m > 0.0:  # a trip in motion skips the stops behind it (as railsim.engine.fleet)
            stops = (stops[0],) + tuple(st for st in stops[1:] if st.window_end_m > start_m)
        for trip_id, dep in zip(svc.trip_ids, svc.departures_s):
            trips.append((float(dep), trip_id, svc.vehicle, route, stops, start_m, float(svc.start_speed_mps)))
    trips.sort(key=lambda x: (x[0], x[1]))
    vtypes = [
        VTypeSpec(
            n,
            v.length_m,
            v.max_speed_mps,
            accel_mps2=0.8,
            decel_mps2=v.service_decel_mps2,
            emergency_decel_mps2=max(v.emergency_decel_mps2, 1.3),
        )
        for n, v in scenario.vehicles.items()
    ]
    cfg = SumoConfig(
        net_file=bundle.net_file,
        additional_files=list(bundle.additional_files) or [bundle.stops_file],
        step_s=float(sim.step_s),
        extra_args=sumo_args(bundle),
        seed=int(sim.seed),
        step_method=sim.step_method,
        vtypes=vtypes,
    )
    t0, c0 = time.perf_counter(), time.process_time()
    steps = 0
    arrived = 0
    with SumoBridge(cfg) as bridge:
        k = 0
        t = bridge.time_s
        while t <= float(sim.duration_s):
            while k < len(trips) and trips[k][0] <= t:
                dep, trip_id, vname, route, stops, start_m, start_v = trips[k]
                e = max(i for i, x in enumerate(route.edge_start_m) if x <= start_m)  # the edge under the front
                route_id = route.id if e == 0 else f"{route.id}@{e}"
                bridge.add_route(route_id, route.edges[e:])
                specs = [
                    StopSpec(s.stop_id, duration_s=1.0 if s.is_destination else s.dwell_s, lane_stop_m=s.lane_stop_m)
                    for s in stops[1:]
                ]
                bridge.add_train(
                    trip_id,
                    route_id,
                    vname,
                    start_m - route.edge_start_m[e],
                    specs,
                    controlled=False,
                    depart_speed_mps=start_v,
                )
                k += 1
            if on_step is not None:
                on_step(t)
            if before_step is not None:
                before_step(bridge)
            bridge.step()
            steps += 1
            arrived += len(bridge.arrived_ids())
            t = bridge.time_s
            if k == len(trips) and not bridge.present_ids() and not bridge.pending_ids():
                break
        sim_s = t
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {"wall_s": wall, "cpu_s": cpu, "sim_s": sim_s, "steps": steps, "n_trains": len(trips), "n_arrived": arrived}
