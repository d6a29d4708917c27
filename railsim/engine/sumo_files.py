"""The SUMO input files of a run folder: vTypes, the trains SUMO was given, and ``.sumocfg`` files to open them.

The engine drives SUMO through libsumo and adds every train at run time, so without these files nothing in a
run folder would load in SUMO's own tools. The bridge (:mod:`railsim.engine.sumo`) hands this module what
SUMO actually got, and it writes, next to ``trips.csv``:

``sumo_vtypes.rou.xml``   the vehicle types of the run (railsim's permissive types: SUMO inserts where told)
``sumo_routes.rou.xml``   every train as inserted: SUMO id, type, depart time and position, its route's edges and
                          its station stops (a turnback unit's later trips are not in it: SUMO got them as
                          re-routes of the running unit)
``sumo_run.sumocfg``      the net, the stop (additional) files and the two files above, with the options the
                          engine started SUMO with (step length, seed, collision checks) and without its outputs
                          — ``sumo-gui -c sumo_run.sumocfg`` shows the scenario driven by SUMO's own model
``sumo_replay.sumocfg``   (only when ``outputs.sumo`` has ``fcd``) the net and stops alone, to replay the run's
                          ``sumo_fcd.xml`` on it with SUMO's ``tools/fcdReplay.py``

Paths to the net and stop files are absolute (they live in the world cache or are the user's files); the
files written here are named relative to the config. Everything is plain text with fixed formatting, so the
same run gives the same bytes.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol
from xml.sax.saxutils import quoteattr

from railsim.record.output import write_bytes
from railsim.record.snapshot import output_file_name

VTYPES_FILE = output_file_name("sumo_vtypes")
ROUTES_FILE = output_file_name("sumo_routes")
RUN_CONFIG = output_file_name("sumo_run")
REPLAY_CONFIG = output_file_name("sumo_replay")

# options of the engine's command line that write files or only quiet SUMO: not in the configs
_OUTPUT_OPTIONS = ("--tripinfo-output", "--stop-output", "--fcd-output", "--collision-output", "--fcd-output.distance")


class VType(Protocol):
    """A SUMO vehicle type (:class:`railsim.engine.sumo.VTypeSpec` has these attributes)."""

    @property
    def type_id(self) -> str: ...
    @property
    def vclass(self) -> str: ...
    @property
    def length_m(self) -> float: ...
    @property
    def max_speed_mps(self) -> float: ...
    @property
    def accel_mps2(self) -> float: ...
    @property
    def decel_mps2(self) -> float: ...
    @property
    def emergency_decel_mps2(self) -> float: ...
    @property
    def tau_s(self) -> float: ...


@dataclass(frozen=True)
class InsertedTrain:
    """One train as SUMO got it: when, where, on which edges, with which stops ``(stop id, duration, until)``."""

    train_id: str
    type_id: str
    depart_s: float
    depart_pos_m: float
    depart_speed_mps: float
    edges: tuple[str, ...]
    stops: tuple[tuple[str, float | None, float | None], ...]


def vtypes_xml(vtypes: Iterable[VType]) -> str:
    """A ``<routes>`` file holding only the vTypes (Krauss with zero ``minGap`` and ``sigma``)."""
    lines = ["<routes>"]
    for vt in vtypes:
        lines.append(
            f'  <vType id={quoteattr(vt.type_id)} vClass={quoteattr(vt.vclass)} length="{vt.length_m:.3f}"'
            f' maxSpeed="{vt.max_speed_mps:.3f}" accel="{vt.accel_mps2:.3f}" decel="{vt.decel_mps2:.3f}"'
            f' emergencyDecel="{vt.emergency_decel_mps2:.3f}" minGap="0" sigma="0" tau="{vt.tau_s:g}"'
            ' carFollowModel="Krauss"/>'
        )
    lines.append("</routes>")
    return "\n".join(lines) + "\n"


def routes_xml(trains: Iterable[InsertedTrain]) -> str:
    """The inserted trains as SUMO ``<vehicle>`` elements with inline routes and stops, sorted by depart time."""
    lines = ["<routes>"]
    for tr in sorted(trains, key=lambda t: (t.depart_s, t.train_id)):
        lines.append(
            f'  <vehicle id={quoteattr(tr.train_id)} type={quoteattr(tr.type_id)} depart="{tr.depart_s:.2f}"'
            f' departPos="{tr.depart_pos_m:.3f}" departSpeed="{tr.depart_speed_mps:.3f}">'
        )
        lines.append(f"    <route edges={quoteattr(' '.join(tr.edges))}/>")
        for stop_id, duration_s, until_s in tr.stops:
            timing = "" if duration_s is None else f' duration="{duration_s:.2f}"'
            timing += "" if until_s is None else f' until="{until_s:.2f}"'
            lines.append(f"    <stop busStop={quoteattr(stop_id)}{timing}/>")
        lines.append("  </vehicle>")
    lines.append("</routes>")
    return "\n".join(lines) + "\n"


def sumocfg_xml(options: Sequence[tuple[str, str]]) -> str:
    """A ``.sumocfg``: one ``<option value="…"/>`` element per ``(option, value)`` under ``<configuration>``."""
    lines = ["<configuration>"]
    lines += [f"    <{name} value={quoteattr(value)}/>" for name, value in options]
    lines.append("</configuration>")
    return "\n".join(lines) + "\n"


def config_options(command_line: Sequence[str]) -> list[tuple[str, str]]:
    """The engine's SUMO command line (``["sumo", "-n", net, "--seed", "1", …]``) as config options.

    ``-n``/``-a`` become ``net-file``/``additional-files``; output options are dropped (running a config must
    not overwrite the run's own ``sumo_*.xml``).
    """
    names = {"-n": "net-file", "-a": "additional-files"}
    args = list(command_line[1:])
    options: list[tuple[str, str]] = []
    for flag, value in zip(args[::2], args[1::2]):
        if flag in _OUTPUT_OPTIONS:
            continue
        options.append((names.get(flag, flag.lstrip("-")), value))
    return options


def write_run_files(
    run_dir: Path,
    command_line: Sequence[str],
    vtypes_file: Path,
    trains: Iterable[InsertedTrain],
    replay: bool,
) -> list[Path]:
    """Write the routes and the config(s) into ``run_dir`` (the vTypes file is already there); return them."""
    run_dir = Path(run_dir)
    routes = run_dir / ROUTES_FILE
    write_bytes(routes, routes_xml(trains).encode("utf-8"))
    options = config_options(command_line)
    additional = [(k, v) for k, v in options if k == "additional-files"]
    rest = [(k, v) for k, v in options if k not in ("net-file", "additional-files")]
    net = [(k, v) for k, v in options if k == "net-file"]
    stops = [(k, ",".join(p for p in v.split(",") if Path(p) != vtypes_file)) for k, v in additional]
    stops_only = [(k, v) for k, v in stops if v]
    run_cfg = run_dir / RUN_CONFIG
    run_options = [*net, *stops_only, ("route-files", f"{vtypes_file.name},{routes.name}"), *rest]
    write_bytes(run_cfg, sumocfg_xml(run_options).encode("utf-8"))
    written = [routes, run_cfg]
    if replay:
        replay_cfg = run_dir / REPLAY_CONFIG
        write_bytes(replay_cfg, sumocfg_xml([*net, *stops_only, *rest]).encode("utf-8"))
        written.append(replay_cfg)
    return written
