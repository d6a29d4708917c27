"""Scale benchmark: microseconds per train-step with N simultaneous trains, railsim beside its bare-SUMO twin.

The scenario is generated: one long double-track ``straight_corridor`` (stations every 3 km, line speed
80 km/h, the demo's 6-car metro unit, ATO + moving-block separation, the demo's lossy, delayed ground radio).
N/2 trains run up and N/2 down, all inserted at t = 0 already in motion (60 km/h), two per section (at 1/4
and 3/4 of it, 1.5 km apart), each on a trip of two sections. From the first step every train is on the
line with a train ahead within the look-ahead, and brakes for, stops at and leaves the stations it reaches;
no trip ends within the horizon, so the number of trains on the line is N in every measured step (checked:
``on_line_at_end``).

For each N the script runs, in separate processes (libsumo hosts one simulation per process):

* **railsim**: the controlled loop (:class:`railsim.engine.loop.Simulation`), clock taken at the start of every
  step (the interval between two marks is one whole step: our phases plus SUMO's ``simulationStep``);
* **sumo**: the bare-SUMO twin — the same trips on the same net inserted at the same places and speeds, driven
  by SUMO's own car-following model (:func:`railsim.studies.baseline.run_sumo_only`);
* **io_floor**: the twin again, with the engine's per-train libsumo traffic added to every step
  (``benchmarks/io_floor.py``: the ids, the bridge's reading and one ``setSpeed`` per train; SUMO keeps driving). No
  railsim logic at all: what any controller driving SUMO train by train through libsumo costs at the least (the
  floor under the railsim column);
* **railsim_interpreted**: the railsim side again on its interpreted modules (``RAILSIM_NATIVE=0``; the railsim
  side runs the compiled core when it is built, ``core`` says: :mod:`railsim.native`);
* **io_floor_busy**: the io floor with unrelated Python work between two steps (summing a field over
  ``BUSY_OBJECTS_PER_TRAIN`` small dicts per train: a working set growing with N like the engine's per-train
  objects). It measures how much dearer
  SUMO's own step gets when the process does anything between steps (the CPU caches are cold when SUMO runs
  again): compare its ``sumo_step_cpu_us_per_train_step`` with io_floor's.

Both measure the steps after ``warmup_steps`` (insertion and first registration excluded) and report wall and
process-CPU microseconds per train-step (step time / N), and their ratio; railsim also reports the CPU time of
SUMO's own ``simulationStep`` inside its loop (libsumo runs in the same process), so the rest is railsim's.
``linearity`` compares the per train-step cost of the largest N with that of the smallest (1.0 = exactly
linear in N).

    .venv/bin/python benchmarks/scale.py [--sizes 100,300,1000,3000] [--horizon-s 100] [--out scale.json]
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import platform
import tempfile
import time
from pathlib import Path
from typing import Any

from spawn import in_process  # benchmarks/spawn.py (the scripts' folder is on sys.path)

SPACING_M = 1500.0  # between consecutive trains of one direction [m]: two per section, at 1/4 and 3/4 of it
STATION_KM = 3.0  # between stations [km]
TRIP_STATIONS = 2  # every trip runs two sections: farther than it gets within the default horizon (100 s)
START_KMH = 60.0


def scenario_mapping(n_trains: int, horizon_s: float, seed: int = 1) -> dict[str, Any]:
    """The generated scenario for ``n_trains`` (a multiple of 4) simultaneous trains, as a scenario mapping.

    Trip ``k`` of a direction starts ``k // 2`` sections from that direction's first station, at 1/4 or 3/4 of
    the section, and runs ``TRIP_STATIONS`` sections (short routes keep the set-up's free-run plans short).
    """
    per_dir = n_trains // 2
    n_stations = (per_dir + 1) // 2 + TRIP_STATIONS + 1
    length_km = (n_stations - 1) * STATION_KM
    services = []
    for direction in ("up", "dn"):
        for k in range(per_dir):
            i = k // 2  # sections from this direction's first station
            a, b = (
                (i + 1, i + 1 + TRIP_STATIONS)
                if direction == "up"
                else (n_stations - i, n_stations - i - TRIP_STATIONS)
            )
            services.append(
                {
                    "id": f"{direction}{k:04d}",
                    "from": f"s{a}",
                    "to": f"s{b}",
                    "vehicle": "cq6",
                    "departures": {"times": [0]},
                    "dwell_s": {"default": 20},
                    "start": {"offset_m": SPACING_M * (0.5 + k % 2), "speed_kmh": START_KMH},
                }
            )
    return {
        "name": f"scale_{n_trains}",
        "description": f"{n_trains} simultaneous trains on a {length_km:g} km corridor (benchmarks/scale.py)",
        "world": {
            "name": "straight_corridor",
            "params": {
                "length_km": length_km,
                "stations": n_stations,
                "line_speed_kmh": 80,
                "platform_length_m": 200,
                "overrun_m": 300,
            },
        },
        "simulation": {"step_s": 0.5, "duration_s": horizon_s, "seed": seed, "step_method": "euler"},
        "vehicles": {"cq6": {"preset": "cq3_6car"}},
        "controllers": {
            "ato": {"type": "ato", "params": {}},
            "sep": {"type": "separation", "params": {"margin_m": 50}},
        },
        "roles": {"ato": "ato", "separation": "sep"},
        "services": services,
        "faults": {"comm": {"t2g": {"delay_s": {"dist": "uniform", "low": 0.1, "high": 0.5}, "loss_prob": 0.01}}},
        "outputs": {"trace_stride_s": 5.0, "sumo": [], "formats": ["csv"]},
    }


def _load(n_trains: int, horizon_s: float) -> Any:
    from railsim.scenario.loading import from_mapping

    return from_mapping(scenario_mapping(n_trains, horizon_s), source="<scale>", base_dir=Path.cwd())


def _per_train_step(marks: list[tuple[float, float]], n_trains: int, warmup_steps: int) -> dict[str, Any]:
    """Wall and CPU µs per train-step over the marked steps after the warm-up (mark k = start of step k)."""
    used = marks[warmup_steps:]
    steps = len(used) - 1
    wall = used[-1][0] - used[0][0]
    cpu = used[-1][1] - used[0][1]
    return {
        "steps_measured": steps,
        "wall_s": wall,
        "cpu_s": cpu,
        "us_per_train_step": 1e6 * wall / (steps * n_trains),
        "cpu_us_per_train_step": 1e6 * cpu / (steps * n_trains),
    }


def _railsim(n_trains: int, horizon_s: float, warmup_steps: int, q: mp.Queue[dict]) -> None:
    from io_floor import time_sumo_steps  # benchmarks/io_floor.py

    from railsim import native
    from railsim.engine.loop import Simulation

    marks: list[tuple[float, float]] = []
    sumo_cpu = time_sumo_steps()  # CPU time of SUMO's own step (libsumo runs in this process), per step

    class Timed(Simulation):
        def _step(self, t: float) -> None:
            marks.append((time.perf_counter(), time.process_time()))
            super()._step(t)

    scn = _load(n_trains, horizon_s)
    with tempfile.TemporaryDirectory() as out:
        sim = Timed(scn, Path(out), progress=False)
        sim.run()
    on_line = [tr for tr in sim.trains.values() if tr.status == "running"]
    steps = len(marks) - 1 - warmup_steps  # SUMO steps between the first and the last measured mark
    q.put(
        {
            **_per_train_step(marks, n_trains, warmup_steps),
            "sumo_step_cpu_us_per_train_step": 1e6
            * sum(sumo_cpu[warmup_steps : warmup_steps + steps])
            / (steps * n_trains),
            "on_line_at_end": len(on_line),
            "core": native.STATUS,
            "collisions": len(sim.safety.collisions),
            "failure": sim.failure(),
        }
    )


def _sumo(n_trains: int, horizon_s: float, warmup_steps: int, q: mp.Queue[dict]) -> None:
    from railsim.studies import baseline

    marks: list[tuple[float, float]] = []
    res = baseline.run_sumo_only(
        _load(n_trains, horizon_s), on_step=lambda _t: marks.append((time.perf_counter(), time.process_time()))
    )
    q.put({**_per_train_step(marks, n_trains, warmup_steps), "n_arrived": res["n_arrived"]})


BUSY_OBJECTS_PER_TRAIN = 300


def _io_floor(n_trains: int, horizon_s: float, warmup_steps: int, q: mp.Queue[dict], busy: bool = False) -> None:
    from io_floor import add_engine_io  # benchmarks/io_floor.py

    from railsim.studies import baseline

    marks: list[tuple[float, float]] = []
    sumo_cpu, engine_io = add_engine_io(BUSY_OBJECTS_PER_TRAIN * n_trains if busy else 0)
    res = baseline.run_sumo_only(
        _load(n_trains, horizon_s),
        on_step=lambda _t: marks.append((time.perf_counter(), time.process_time())),
        before_step=engine_io,
    )
    steps = len(marks) - 1 - warmup_steps
    q.put(
        {
            **_per_train_step(marks, n_trains, warmup_steps),
            "sumo_step_cpu_us_per_train_step": 1e6
            * sum(sumo_cpu[warmup_steps : warmup_steps + steps])
            / (steps * n_trains),
            "n_arrived": res["n_arrived"],
        }
    )


def _io_floor_busy(n_trains: int, horizon_s: float, warmup_steps: int, q: mp.Queue[dict]) -> None:
    _io_floor(n_trains, horizon_s, warmup_steps, q, busy=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    ap.add_argument("--sizes", default="100,300,1000,3000", help="numbers of simultaneous trains (even)")
    ap.add_argument("--horizon-s", type=float, default=100.0, help="simulated seconds per run")
    ap.add_argument("--warmup-steps", type=int, default=10, help="steps left out of the measurement")
    ap.add_argument("--out", type=Path, default=None, help="also write the JSON here")
    args = ap.parse_args()
    sizes = [int(x) for x in args.sizes.split(",")]
    rows = []
    for n in sizes:
        in_process(_sumo, n, 1.0, 0)  # build and cache the corridor, so neither side pays for netconvert
        sumo = in_process(_sumo, n, args.horizon_s, args.warmup_steps)
        floor = in_process(_io_floor, n, args.horizon_s, args.warmup_steps)
        busy = in_process(_io_floor_busy, n, args.horizon_s, args.warmup_steps)
        ours = in_process(_railsim, n, args.horizon_s, args.warmup_steps)
        interp = in_process(_railsim, n, args.horizon_s, args.warmup_steps, env={"RAILSIM_NATIVE": "0"})
        rows.append(
            {
                "n_trains": n,
                "railsim": ours,
                "sumo": sumo,
                "io_floor": floor,
                "io_floor_busy": busy,
                "ratio": ours["us_per_train_step"] / sumo["us_per_train_step"],
                "cpu_ratio": ours["cpu_us_per_train_step"] / sumo["cpu_us_per_train_step"],
                "floor_cpu_ratio": floor["cpu_us_per_train_step"] / sumo["cpu_us_per_train_step"],
                # railsim's own per train-step: its whole step less SUMO's step inside it
                "railsim_own_cpu_us_per_train_step": ours["cpu_us_per_train_step"]
                - ours["sumo_step_cpu_us_per_train_step"],
                # the same on railsim's interpreted modules (RAILSIM_NATIVE=0), in the same run
                "railsim_interpreted": interp,
                "interpreted_own_cpu_us_per_train_step": interp["cpu_us_per_train_step"]
                - interp["sumo_step_cpu_us_per_train_step"],
            }
        )
        print(
            f"N={n}: railsim {ours['us_per_train_step']:.1f} us (cpu {ours['cpu_us_per_train_step']:.1f}, of it "
            f"SUMO's step {ours['sumo_step_cpu_us_per_train_step']:.1f}), sumo {sumo['us_per_train_step']:.1f} us "
            f"(cpu {sumo['cpu_us_per_train_step']:.1f}), io floor cpu {floor['cpu_us_per_train_step']:.1f} "
            f"(SUMO's step {floor['sumo_step_cpu_us_per_train_step']:.1f}; busy between steps "
            f"{busy['sumo_step_cpu_us_per_train_step']:.1f}); interpreted railsim cpu "
            f"{interp['cpu_us_per_train_step']:.1f} per train-step",
            flush=True,
        )
    first, last = rows[0]["railsim"], rows[-1]["railsim"]
    result = {
        "benchmark": "scale",
        "python": platform.python_version(),
        "horizon_s": args.horizon_s,
        "warmup_steps": args.warmup_steps,
        "core": first["core"],  # railsim.native: the compiled core, or why not
        "rows": rows,
        "linearity": {
            "n": [sizes[0], sizes[-1]],
            "cpu_per_train_step_ratio": last["cpu_us_per_train_step"] / first["cpu_us_per_train_step"],
        },
    }
    text = json.dumps(result, indent=2)
    print(text)
    if args.out is not None:
        args.out.write_text(text + "\n")


if __name__ == "__main__":
    main()
