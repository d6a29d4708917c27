"""Paper D's figures (spec 003 §5: position, speed, acceleration and spacing curves of L, F1, F2) from an engine run.

The paper draws, for each scenario, the three vehicles' positions, speeds and accelerations over time and the
spacing between consecutive vehicles, with the moments the collision-avoidance (CA) trigger fires. These figures
are drawn from an output folder (``trace.csv``, ``events.csv``, ``scenario.resolved.yaml``) through
:func:`railsim.analysis.paper003.metrics`' reading of pairs and CA intervals:

* ``positions.png`` — front chainage minus the rearmost train's starting chainage (so the plot starts near 0 m,
  like the paper's relative coordinates);
* ``speeds.png``, ``accelerations.png`` (the applied acceleration, after the plant's limits and lag);
* ``gaps.png`` — net front-to-rear gap of each consecutive pair, the CA safety distance in force (dashed; the
  fixed 28 m or the speed-dependent RDBM/ADBM curve, recomputed like the controller does) and the follower's CA
  intervals shaded.

Uses the non-interactive Agg backend; :func:`write_figures` writes PNGs and returns their paths.
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import yaml  # noqa: E402

from controllers.monorail.braking_modes import required_gap_m  # noqa: E402
from railsim.analysis import paper003 as ca_metrics  # noqa: E402


def _series(out: Path) -> tuple[np.ndarray, dict[str, dict[str, np.ndarray]]]:
    rows = ca_metrics._read_csv(out / "trace.csv")
    times = np.unique(np.array([float(r["t_s"]) for r in rows]))
    out_s: dict[str, dict[str, np.ndarray]] = {}
    for r in rows:
        d = out_s.setdefault(r["train"], {k: np.full(len(times), np.nan) for k in ("x", "v", "a")})
        j = int(np.searchsorted(times, float(r["t_s"])))
        d["x"][j], d["v"][j], d["a"][j] = float(r["chainage_m"]), float(r["speed_mps"]), float(r["applied_accel_mps2"])
    return times, out_s


def write_figures(out_dir: Path | str, dest: Path | str) -> list[Path]:
    """Write the four figures of the run in ``out_dir`` into ``dest``; returns the PNG paths."""
    out, dest = Path(out_dir), Path(dest)
    dest.mkdir(parents=True, exist_ok=True)
    raw = yaml.safe_load((out / "scenario.resolved.yaml").read_text(encoding="utf-8"))
    name = str(raw.get("name", out.name))
    m = ca_metrics.metrics(out)
    times, s = _series(out)
    order = sorted(s, key=lambda tid: -float(s[tid]["x"][~np.isnan(s[tid]["x"])][0]))
    x0 = min(float(np.nanmin(d["x"])) for d in s.values())
    paths: list[Path] = []
    for key, ylabel, fname, scale in (
        ("x", "position [m]", "positions.png", None),
        ("v", "speed [km/h]", "speeds.png", 3.6),
        ("a", "acceleration [m/s²]", "accelerations.png", 1.0),
    ):
        fig, ax = plt.subplots(figsize=(8, 4.5), constrained_layout=True)
        for tid in order:
            y = s[tid][key] - x0 if scale is None else s[tid][key] * scale
            ax.plot(times, y, lw=1.3, label=tid.split(".")[0])
        _mark_ca(ax, m)
        ax.set_xlabel("time [s]")
        ax.set_ylabel(ylabel)
        ax.set_title(f"{name}: {ylabel.split(' [')[0]}")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        paths.append(dest / fname)
        fig.savefig(paths[-1], dpi=110)
        plt.close(fig)
    fig, ax = plt.subplots(figsize=(8, 4.5), constrained_layout=True)
    for n, (ahead, fol) in enumerate(zip(order, order[1:])):
        gap = s[ahead]["x"] - _length(raw, ahead) - s[fol]["x"]
        colour = f"C{n}"
        ax.plot(times, gap, lw=1.4, color=colour, label=f"{ahead.split('.')[0]}→{fol.split('.')[0]} gap")
        params = ca_metrics._ca_params(raw, _service(raw, fol))
        if params is not None:
            policy, b_e = params.policy(), _decel(raw, fol)
            trig = [
                required_gap_m(policy, max(vf, 0.0), max(va, 0.0), b_e)
                if not (math.isnan(vf) or math.isnan(va))
                else math.nan
                for vf, va in zip(s[fol]["v"], s[ahead]["v"])
            ]
            ax.plot(times, trig, lw=1.0, ls="--", color=colour, label=f"CA trigger of {fol.split('.')[0]}")
        for t0, t1 in m["ca_intervals"].get(fol, []):
            ax.axvspan(t0, t1 if t1 is not None else times[-1], color=colour, alpha=0.15)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("net gap [m]")
    ax.set_title(f"{name}: spacing (shaded: CA active)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    paths.append(dest / "gaps.png")
    fig.savefig(paths[-1], dpi=110)
    plt.close(fig)
    return paths


def _mark_ca(ax, m: dict) -> None:
    """Thin vertical lines at CA triggers (solid) and releases (dotted)."""
    for ivs in m["ca_intervals"].values():
        for t0, t1 in ivs:
            ax.axvline(t0, color="grey", lw=0.6)
            if t1 is not None:
                ax.axvline(t1, color="grey", lw=0.6, ls=":")


def _service(raw: dict, train_id: str) -> str:
    return train_id.rsplit(".", 1)[0]


def _length(raw: dict, train_id: str) -> float:
    return float(ca_metrics._vehicle_of(raw, _service(raw, train_id)).get("length_m", 0.0))


def _decel(raw: dict, train_id: str) -> float:
    return float(ca_metrics._vehicle_of(raw, _service(raw, train_id)).get("emergency_decel_mps2", math.inf))


__all__ = ["write_figures"]
