"""Shared helpers for tests that run SUMO: every SUMO run happens in a child process.

A SUMO crash kills the Python interpreter under libsumo, so a test that runs a simulation starts a child process
(``railsim run`` or a small script) and inspects what it wrote. One crash fails one test. :func:`run_railsim`'s
children are forked from a server that has imported railsim already (:mod:`tests.forkserver`): the same command in
its own process, without a second and a half of interpreter start and imports each.
"""

from __future__ import annotations

import csv
import fcntl
import json
import os
import subprocess
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from types import SimpleNamespace
from typing import TYPE_CHECKING, Any, TypeVar

import pytest

if TYPE_CHECKING:
    from railsim.engine.train import TrainRuntime

T = TypeVar("T", bound="TrainRuntime")

ROOT = Path(__file__).resolve().parents[1]
DATA = Path(__file__).resolve().parent / "data"


def railsim_cmd() -> list[str]:
    return [sys.executable, "-m", "railsim.cli.main"]


def run_railsim(
    args: list[str], cache_dir: Path | None = None, timeout: float = 600, reference: bool = False
) -> subprocess.CompletedProcess:
    """``python -m railsim.cli.main ARGS`` in a child process (forked from :mod:`tests.forkserver`), from the
    clone's folder; its exit code and text output as :func:`subprocess.run` gives them. ``reference``: on railsim's
    interpreted modules (``RAILSIM_NATIVE=0``), not the compiled core (:mod:`railsim.native`)."""
    from tests import forkserver

    env = dict(os.environ)
    if cache_dir is not None:
        env["RAILSIM_CACHE"] = str(cache_dir)
    if reference:
        env["RAILSIM_NATIVE"] = "0"
    return forkserver.run(args, env=env, cwd=ROOT, timeout=timeout)


def ok_stdout(res: subprocess.CompletedProcess) -> str:
    """The stdout of a railsim command that must have succeeded (its stderr and stdout in the failure message)."""
    assert res.returncode == 0, res.stderr + res.stdout
    return str(res.stdout)


def run_python(
    code: str, cache_dir: Path | None = None, timeout: float = 600, reference: bool = False
) -> subprocess.CompletedProcess:
    """``python -c CODE`` in a child process from the clone's folder. ``reference``: the child loads railsim's
    interpreted modules (``RAILSIM_NATIVE=0``, :mod:`railsim.native`) — for code that patches or subclasses the
    engine's internals to watch them, which the compiled core's classes do not allow."""
    env = dict(os.environ)
    if cache_dir is not None:
        env["RAILSIM_CACHE"] = str(cache_dir)
    if reference:
        env["RAILSIM_NATIVE"] = "0"
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout, env=env, cwd=ROOT
    )


def read_csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def read_summary(out: Path) -> dict[str, Any]:
    return json.loads((out / "summary.json").read_text(encoding="utf-8"))


def mini_line() -> dict[str, Any]:
    """The mini line scenario (:file:`tests/data/scenarios/mini_line.yaml`) as a mapping, its world made absolute
    so a changed copy can be written anywhere."""
    import yaml

    data: dict[str, Any] = yaml.safe_load((DATA / "scenarios" / "mini_line.yaml").read_text(encoding="utf-8"))
    data["world"] = {"line": str(DATA / "lines" / "mini_y.yaml")}
    return data


def merge_world(
    pairs: Sequence[tuple[float, float]], others: Sequence[tuple[str, str, float]] = (), duration_s: float = 1800.0
) -> dict[str, Any]:
    """A scenario on the generated Y world :file:`tests/data/lines/merge_y.yaml` (a branch merging at ``c_down``).

    Formation ``m<k>``: a leader from E and a follower from G, both to A, leaving at ``pairs[k]`` (leader,
    follower), coupling after ``c_down`` with a 30 m target gap; leaders are trips of service ``lead``, followers
    of ``fol``, each numbered in departure order. ``others``: unrelated trains ``(service id, origin e or g,
    departure)`` to A, one service each."""
    order_l = sorted(range(len(pairs)), key=lambda k: pairs[k][0])
    order_f = sorted(range(len(pairs)), key=lambda k: pairs[k][1])
    trains = [("lead", "e", [pairs[k][0] for k in order_l]), ("fol", "g", [pairs[k][1] for k in order_f])]
    trains += [(sid, origin, [depart_s]) for sid, origin, depart_s in others]
    services = [
        {"id": sid, "from": origin, "to": "a", "vehicle": "cq6", "departures": {"times": times}, "dwell_s": 20}
        for sid, origin, times in trains
    ]
    formations = [
        {
            "id": f"m{k}",
            "leader": {"service": "lead", "trip": order_l.index(k)},
            "follower": {"service": "fol", "trip": order_f.index(k)},
            "target_gap_m": 30.0,
            "couple": {"after_switch": "c_down"},
        }
        for k in range(len(pairs))
    ]
    return {
        "name": "merge_y_formations",
        "world": {"line": str(DATA / "lines" / "merge_y.yaml")},
        "simulation": {"step_s": 0.5, "duration_s": duration_s, "seed": 7, "step_method": "euler"},
        "vehicles": {"cq6": {"preset": "cq3_6car"}},
        "controllers": {
            "ato": {"type": "ato"},
            "sep": {"type": "separation", "params": {"margin_m": 50}},
            "vc": {"type": "cacc"},
        },
        "roles": {"ato": "ato", "separation": "sep", "coupled": "vc"},
        "services": services,
        "formations": formations,
        "outputs": {"trace_stride_s": 1.0, "sumo": [], "formats": ["csv"]},
    }


def run_mapping(
    folder: Path, data: dict[str, Any], name: str = "scenario", timeout: float = 600
) -> tuple[subprocess.CompletedProcess, Path]:
    """Write ``data`` as ``folder/name.yaml``, ``railsim run`` it into ``folder/name``; (the process, the outputs)."""
    import yaml

    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    out = folder / name
    return run_railsim(["run", str(path), "--out", str(out), "--no-progress"], timeout=timeout), out


def run_clean(folder: Path, data: dict[str, Any], name: str) -> tuple[Path, list[dict[str, Any]]]:
    """:func:`run_mapping`, and require a clean run (exit 0, no collision of railsim's or SUMO's, no switch
    violation, every trip arrived); (the outputs, the events with ``detail`` parsed and ``t_s`` a float)."""
    res, out = run_mapping(folder, data, name)
    assert res.returncode == 0, res.stderr[-2000:]
    summary = read_summary(out)
    assert summary["collisions"] == 0 and summary["sumo_collisions"] == 0 and summary["switch_violations"] == 0
    assert summary["n_arrived"] == summary["n_trains"]
    return out, read_events(out)


def read_events(out: Path) -> list[dict[str, Any]]:
    """``events.csv`` of run folder ``out``, each row with ``detail`` parsed and ``t_s`` a float."""
    events: list[dict[str, Any]] = list(read_csv(out / "events.csv"))
    for e in events:
        e["detail"] = json.loads(e["detail"]) if e["detail"] else {}
        e["t_s"] = float(e["t_s"])
    return events


def interpreted(module: Any) -> Any:
    """A fresh copy of ``module`` with numba's JIT off (``NUMBA_DISABLE_JIT`` for that module alone): every
    ``@njit`` function in it is the plain Python function as written — the reference its compiled form must give
    the same bits as. The copy is not registered in ``sys.modules``; the module's own imports are shared."""
    import importlib.util

    from numba import config

    spec = importlib.util.spec_from_file_location(f"{module.__name__}_interpreted", module.__file__)
    assert spec is not None and spec.loader is not None
    copy = importlib.util.module_from_spec(spec)
    disabled = config.DISABLE_JIT
    config.DISABLE_JIT = True
    try:
        spec.loader.exec_module(copy)
    finally:
        config.DISABLE_JIT = disabled
    return copy


def session_shared_dir(factory: pytest.TempPathFactory) -> Path:
    """A folder shared by every xdist worker of this test session (the session's temporary root), not by others."""
    base = factory.getbasetemp()
    root = base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base
    shared = root / "shared"
    shared.mkdir(exist_ok=True)
    return shared


def shared_run(factory: pytest.TempPathFactory, name: str, make: Callable[[Path], None]) -> Path:
    """The folder ``name`` made once per test session by ``make(folder)``, whichever worker asks first.

    The first caller makes it under an exclusive lock and marks it done; later callers (any worker) wait for the
    lock and return the folder. A ``make`` that raises leaves no mark, so the next caller tries again and fails
    with its own error instead of reading half a run.
    """
    root = session_shared_dir(factory)
    folder = root / name
    with open(root / f"{name}.lock", "w", encoding="utf-8") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        done = root / f"{name}.done"
        if not done.exists():
            folder.mkdir(exist_ok=True)
            make(folder)
            done.touch()
    return folder


def route_view(route_id: str, edges: tuple[str, ...], lengths_m: tuple[float, ...]) -> Any:
    """A :class:`~railsim.engine.routeview.RouteView` of a made-up route: ``edges`` end to end with these lengths, no
    restrictions, no gradients (an edge may come twice: a loop)."""
    import numpy as np

    from railsim.engine.routeview import RouteView

    starts = np.concatenate([[0.0], np.cumsum(lengths_m)[:-1]])
    return RouteView(
        SimpleNamespace(
            id=route_id,
            edges=edges,
            edge_start_m=tuple(float(x) for x in starts),
            speed_limits=(),
            gradients=(),
            length_m=float(sum(lengths_m)),
        )
    )


def runtime_train(cls: type[T], train_id: str, view: Any, length_m: float, **fields: Any) -> T:
    """A train of class ``cls`` (:class:`~railsim.engine.train.TrainRuntime` or a subclass) on ``view``, its trip and
    vehicle plain objects with the id and length only, no controllers; ``fields`` are set on it (its resident fields
    through their properties)."""
    trip = SimpleNamespace(trip_id=train_id, vehicle=SimpleNamespace(length_m=length_m))
    tr = cls(trip=trip, view=view, controllers={})  # type: ignore[arg-type]
    for name, value in fields.items():
        setattr(tr, name, value)
    return tr


def standing_train(train_id: str, front_m: float = 0.0, **fields: Any) -> SimpleNamespace:
    """A train standing on the line for no reason of its own, with the fields the stall watchdog reads (not dwelling,
    not held, on the line, one edge); ``fields`` add to them (the route-lock port's ``locks``, ``released``)."""
    return SimpleNamespace(
        train_id=train_id,
        plant=SimpleNamespace(speed_mps=0.0),
        hold_until_s=None,
        sumo_stopped=False,
        sumo_stopped_now=False,
        held_for_route=False,
        on_line=True,
        arrived_s=None,
        front_m=front_m,
        view=SimpleNamespace(edges=["track"], edge_at=lambda _m: 0),
        **fields,
    )
