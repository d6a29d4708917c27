"""A/B benchmark: this working tree against another commit, on the same scenario, in the same run.

A change to the engine that saves a few per cent is below what CPU time can resolve on a shared machine (run to
run it varies by ±10 % and more). Two measures are offered:

* ``--measure instructions`` (the default): the instructions each side executes, counted by valgrind's
  cachegrind (``--cache-sim=no``). They do not depend on the load or the clock, so one run of each side is an
  answer to a fraction of a per cent (both sides run with ``PYTHONHASHSEED=0``; with string hashing random, two
  runs of the same code differ by up to ~0.1 %). Each side runs twice and the second run counts: numba keeps its compiled
  kernels per CPU model, and valgrind's emulated CPU is another model, so a side's first run under valgrind
  compiles every kernel anew (tens of billions of instructions). The sides run side by side (``--jobs``): load
  does not change a count. A run is ~70× slower than without valgrind; the default cut of the demo (1,500 s)
  takes about 4 minutes a run.
* ``--measure cpu``: process CPU time of ``--reps`` alternating pairs of runs (after one warm-up run of each side,
  which compiles its kernels), nothing else in the same process: medians and the per-pair ratios.

Both sides run in ``git worktree`` s made side by side in a temporary folder and removed at the end: ``base`` at
that commit, ``head`` at this checkout's HEAD with its uncommitted changes applied and its untracked files (those
git does not ignore) copied. ``--core compiled`` (the default: what ``make demo`` runs) builds each side's compiled
core in its worktree first (:mod:`railsim.native`; about three minutes, both at once) and checks that every run
loaded it; ``--core interpreted`` runs both on their interpreted modules (``RAILSIM_NATIVE=0``), and is the only
choice for a base older than the compiled core. Alike folders matter to a count: the same code run from this
checkout and from a fresh worktree differed by 0.1-0.5 % (paths, and the caches already in the folder). Each side imports its own
``railsim`` (``PYTHONPATH``) and runs its own copy of the scenario file (``--scenario`` is a path inside the tree;
an absolute path is used by both). Both sides use this checkout's virtual environment.
Prints one JSON object: each side's runs and value, and ``ratio`` = this tree ÷ base (below 1: this tree does
less).

    .venv/bin/python benchmarks/ab.py BASE [--measure instructions|cpu] [--core compiled|interpreted]
        [--duration-s 1500] [--reps 3] [--keep DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_SCENARIO = "scenarios/chongqing_line3_peak.yaml"

# one side's run, in its own process: the scenario cut to the horizon, run into a temporary folder; one JSON line
CHILD = """
import json, sys, tempfile, time
from pathlib import Path
from railsim import api, native, scenario
scn = scenario.load(sys.argv[1], {"simulation.duration_s": float(sys.argv[2])})
with tempfile.TemporaryDirectory() as out:
    c0 = time.process_time()
    s = api.run(scn, Path(out), seed=int(sys.argv[3]), progress=False)
    cpu_s = time.process_time() - c0
print(json.dumps({"cpu_s": cpu_s, "n_arrived": s.get("n_arrived"), "collisions": s.get("collisions"),
                  "status": s.get("status"), "core": native.STATUS}))
"""


class AbError(Exception):
    """A one-line reason the comparison cannot run (exit 2)."""


def summary_instructions(text: str) -> int:
    """The instruction count in a cachegrind output file (its ``summary:`` line; the first event is ``Ir``)."""
    for line in text.splitlines():
        if line.startswith("summary:"):
            fields = line.split()[1:]
            if fields and fields[0].isdigit():
                return int(fields[0])
    raise AbError("cachegrind wrote no 'summary:' line")


def _git(*args: str) -> str:
    """``git`` in this checkout; its last line of complaint as an :class:`AbError`."""
    try:
        done = subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, text=True)
    except FileNotFoundError:
        raise AbError("git is not installed") from None
    if done.returncode != 0:
        why = (done.stderr.strip().splitlines() or ["failed"])[-1]
        raise AbError(f"git {' '.join(args)}: {why}")
    return done.stdout.strip()


def _commit_of(rev: str) -> str:
    """The commit ``rev`` names in this checkout."""
    try:
        return _git("rev-parse", "--verify", "--quiet", f"{rev}^{{commit}}")
    except AbError:
        raise AbError(f"base: no commit {rev!r} in {ROOT}") from None


def _carry_changes(tree: Path) -> None:
    """This checkout's uncommitted work into ``tree`` (a worktree of HEAD): the changes to tracked files as a patch,
    and the untracked files git does not ignore, copied."""
    got = subprocess.run(["git", "-C", str(ROOT), "diff", "HEAD", "--binary"], capture_output=True)
    if got.returncode != 0:
        raise AbError(f"git diff HEAD: {(got.stderr.decode().strip().splitlines() or ['failed'])[-1]}")
    diff = got.stdout
    if diff:
        done = subprocess.run(["git", "-C", str(tree), "apply", "--binary", "-"], input=diff, capture_output=True)
        if done.returncode != 0:
            raise AbError(f"the uncommitted changes do not apply to a copy of HEAD: {done.stderr.decode().strip()}")
    for name in filter(None, _git("ls-files", "--others", "--exclude-standard", "-z").split("\0")):
        (tree / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(ROOT / name, tree / name)


def _core_env(tree: Path, core: str) -> dict[str, str]:
    """The environment of a process of the side in ``tree``: its own ``railsim``, string hashing fixed, and the
    compiled core or the interpreted modules (``RAILSIM_NATIVE``)."""
    # string hashing fixed: sets and dicts of ids then hold the same layout in every run, and two runs of the same
    # code differ in a count only by what other threads do (OpenBLAS's)
    env = {**os.environ, "PYTHONPATH": str(tree), "PYTHONHASHSEED": "0"}
    env.pop("RAILSIM_NATIVE", None)
    if core == "interpreted":
        env["RAILSIM_NATIVE"] = "0"
    return env


def _build_core(name: str, tree: Path) -> None:
    """Compile the side's core in its worktree (``python -m railsim.compile_core``); :class:`AbError` if it has
    none or the build fails."""
    if not (tree / "railsim" / "compile_core.py").is_file():
        raise AbError(f"{name} has no compiled core (railsim/compile_core.py): compare with --core interpreted")
    print(f"ab: {name}: building its compiled core", file=sys.stderr, flush=True)
    cmd = [sys.executable, "-m", "railsim.compile_core"]
    done = subprocess.run(cmd, cwd=tree, env=_core_env(tree, "compiled"), capture_output=True, text=True)
    if done.returncode != 0:
        tail = (done.stderr.strip().splitlines() or ["no output"])[-1]
        raise AbError(f"the compiled core of {name} did not build (exit {done.returncode}): {tail}")


def _run_side(
    tree: Path, scenario: str, duration_s: float, seed: int, cg_out: Path | None, core: str
) -> dict[str, Any]:
    """One run of the side in ``tree`` (under cachegrind when ``cg_out`` is given) on ``core``: the child's line,
    and the instruction count."""
    cmd = [sys.executable, "-c", CHILD, scenario, repr(duration_s), str(seed)]
    if cg_out is not None:
        cmd = ["valgrind", "--tool=cachegrind", "--cache-sim=no", f"--cachegrind-out-file={cg_out}", *cmd]
    done = subprocess.run(cmd, cwd=tree, env=_core_env(tree, core), capture_output=True, text=True)
    lines = [ln for ln in done.stdout.splitlines() if ln.startswith("{")]
    if done.returncode != 0 or not lines:
        tail = (done.stderr.strip().splitlines() or ["no output"])[-1]
        raise AbError(f"the run in {tree} failed (exit {done.returncode}): {tail}")
    res: dict[str, Any] = json.loads(lines[-1])
    if core == "compiled" and not str(res.get("core", "")).startswith("compiled"):
        raise AbError(f"the run in {tree} did not load its compiled core: {res.get('core')}")
    if cg_out is not None:
        res["instructions"] = summary_instructions(cg_out.read_text())
    return res


def _side(tree: Path, args: argparse.Namespace, name: str, work: Path) -> list[dict[str, Any]]:
    """The instruction-count runs of one side (the last counts)."""
    runs = []
    for k in range(args.runs):
        print(f"ab: {name}: run {k + 1}/{args.runs} under valgrind", file=sys.stderr, flush=True)
        runs.append(_run_side(tree, args.scenario, args.duration_s, args.seed, work / f"cg_{name}_{k}.out", args.core))
    return runs


def compare(sides: dict[str, Path], args: argparse.Namespace, work: Path) -> dict[str, Any]:
    """Both sides (``base`` and ``head``, each a tree) measured: ``{"base": ..., "head": ..., "ratio": head /
    base}``."""
    out: dict[str, Any] = {}
    if args.core == "compiled":  # both at once: a build is one core's work
        with ThreadPoolExecutor(max_workers=2) as pool:
            for built in [pool.submit(_build_core, name, tree) for name, tree in sides.items()]:
                built.result()
    if args.measure == "instructions":
        with ThreadPoolExecutor(max_workers=args.jobs) as pool:
            futures = {name: pool.submit(_side, tree, args, name, work) for name, tree in sides.items()}
            for name, fut in futures.items():
                runs = fut.result()
                out[name] = {"runs": runs, "value": runs[-1]["instructions"]}
    else:
        runs_of: dict[str, list[dict[str, Any]]] = {name: [] for name in sides}
        for name, tree in sides.items():  # compiles the side's kernels (a fresh worktree has none cached)
            print(f"ab: {name}: warm-up run", file=sys.stderr, flush=True)
            _run_side(tree, args.scenario, args.duration_s, args.seed, None, args.core)
        for k in range(args.reps):
            for name, tree in sides.items():
                print(f"ab: {name}: run {k + 1}/{args.reps}", file=sys.stderr, flush=True)
                runs_of[name].append(_run_side(tree, args.scenario, args.duration_s, args.seed, None, args.core))
        for name, runs in runs_of.items():
            out[name] = {"runs": runs, "value": statistics.median(r["cpu_s"] for r in runs)}
        out["pair_ratios"] = [h["cpu_s"] / b["cpu_s"] for b, h in zip(runs_of["base"], runs_of["head"], strict=True)]
    for name in sides:
        same = {(r["n_arrived"], r["collisions"], r["status"]) for r in out[name]["runs"]}
        out[name]["outcome"] = [list(o) for o in sorted(same, key=repr)]
    # the same trips arrived, the same collisions: else the counts compare two different runs
    out["same_outcome"] = out["base"]["outcome"] == out["head"]["outcome"]
    out["ratio"] = out["head"]["value"] / out["base"]["value"]
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    ap.add_argument("base", help="the commit to compare this working tree with (any git revision)")
    ap.add_argument("--measure", choices=("instructions", "cpu"), default="instructions")
    ap.add_argument("--core", choices=("compiled", "interpreted"), default="compiled", help="what both sides run")
    ap.add_argument("--scenario", default=DEFAULT_SCENARIO, help="path inside each tree, or absolute")
    ap.add_argument("--duration-s", type=float, default=1500.0, help="the scenario's horizon for both sides")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--runs", type=int, default=2, help="instructions: runs per side, the last counts")
    ap.add_argument("--jobs", type=int, default=2, help="instructions: sides run at once")
    ap.add_argument("--reps", type=int, default=3, help="cpu: alternating pairs after the warm-up")
    ap.add_argument("--keep", type=Path, help="instructions: copy cachegrind's files here (for cg_diff, cg_annotate)")
    args = ap.parse_args(argv)
    try:
        if not args.duration_s > 0.0 or args.duration_s == float("inf"):
            raise AbError(f"--duration-s must be a positive finite number of seconds, not {args.duration_s!r}")
        if min(args.runs, args.jobs, args.reps) < 1:
            raise AbError("--runs, --jobs and --reps must be at least 1")
        if args.measure == "instructions" and shutil.which("valgrind") is None:
            raise AbError("valgrind is not installed (apt: valgrind); or use --measure cpu")
        commit = _commit_of(args.base)
        head = _git("rev-parse", "HEAD")
        changed = bool(_git("status", "--porcelain", "--untracked-files=no"))
        with tempfile.TemporaryDirectory(prefix="railsim-ab-") as tmp:
            work = Path(tmp)
            sides = {"base": work / "base", "head": work / "head"}  # alike: the same path length, no caches yet
            made: list[Path] = []
            try:
                for name, rev in (("base", commit), ("head", head)):
                    _git("worktree", "add", "--detach", str(sides[name]), rev)
                    made.append(sides[name])
                _carry_changes(sides["head"])
                result = compare(sides, args, work)
                if args.keep is not None and args.measure == "instructions":
                    args.keep.mkdir(parents=True, exist_ok=True)
                    for f in sorted(work.glob("cg_*.out")):
                        shutil.copy2(f, args.keep / f.name)
            finally:
                for tree in made:
                    _git("worktree", "remove", "--force", str(tree))
    except AbError as exc:
        print(f"ab: {exc}", file=sys.stderr)
        return 2
    report = {
        "benchmark": "ab",
        "measure": args.measure,
        "core": args.core,
        "scenario": args.scenario,
        "duration_s": args.duration_s,
        "seed": args.seed,
        "python": platform.python_version(),
        "base_commit": commit,
        "head_commit": head,
        "head_has_uncommitted_changes": changed,
        **result,
    }
    print(json.dumps(report, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
