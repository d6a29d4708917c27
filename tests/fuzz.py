"""A seeded mutator over the shipped scenarios, and the fuzz harness around ``railsim validate`` and ``railsim run``.

No input may break validation. :func:`mutants` turns the shipped scenarios (``scenarios/*.yaml``) into
hostile variants, deterministically from a seed; mutant ``k`` is the same text on every machine. Three families
of mutation, one to three per mutant:

* **tree** — on the parsed mapping: a leaf replaced by a hostile value (``inf``, ``nan``, ``1e308``, ``-9.2e18``,
  ``1e-300``, ``2**63``, a bool, ``None``, an empty or 500-character string, an empty list or mapping), a number
  scaled (×0, ×−1, ×1e-6, ×1e6, ×1e300), a key deleted, a misspelt key added, a list emptied or an item
  duplicated, a subtree replaced by a scalar, a value wrapped 60 levels deep;
* **files** — ``world`` pointed at ``/dev/zero``, ``/etc/passwd``, a directory, ``/dev/null``, a missing file;
* **text** — on the YAML text: an alias bomb under ``description``, 5,000 levels of ``[``, a 5,000-digit integer,
  truncation, a character replaced by YAML punctuation, NUL or a tab, invalid UTF-8 bytes.

:func:`validate_in_process` runs ``railsim validate --no-world-check`` through :func:`railsim.cli.main.main` in
this process with a per-mutant time limit (``SIGALRM``; a hang is a :class:`Hang`, which ``main``'s last guard
cannot swallow) and classifies the outcome. ``python -m tests.fuzz --mutants 5000`` prints the figures of a larger
campaign (and with ``--runs N`` also runs N accepted mutants for a few simulated seconds in child processes).
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import io
import json
import math
import random
import signal
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = sorted((ROOT / "scenarios").glob("*.yaml"))

HOSTILE_VALUES: tuple[Any, ...] = (
    math.inf,
    -math.inf,
    math.nan,
    1e308,
    -1e308,
    1e-300,
    -9.2e18,
    2**63,
    -1,
    0,
    0.5,
    True,
    None,
    "",
    "x" * 500,
    "07:30",
    [],
    {},
    [1, 2, 3],
    {"a": 1},
)
SCALES = (0.0, -1.0, 1e-6, 1e6, 1e300)
HOSTILE_PATHS = ("/dev/zero", "/etc/passwd", "/tmp", "/dev/null", "/nonexistent/world.yaml")
PUNCTUATION = (":", "[", "{", "]", "}", "&", "*", "!", "%", "\t", "\x00", "-", "#", "'", '"', "|", ">")
ALIAS_BOMB = (
    "[&a [lol,lol,lol,lol,lol,lol,lol,lol,lol], &b [*a,*a,*a,*a,*a,*a,*a,*a,*a], "
    "&c [*b,*b,*b,*b,*b,*b,*b,*b,*b], &d [*c,*c,*c,*c,*c,*c,*c,*c,*c], &e [*d,*d,*d,*d,*d,*d,*d,*d,*d], "
    "&f [*e,*e,*e,*e,*e,*e,*e,*e,*e], &g [*f,*f,*f,*f,*f,*f,*f,*f,*f], &h [*g,*g,*g,*g,*g,*g,*g,*g,*g]]"
)
TIMEOUT_S = 10.0  # per mutant; a healthy validate takes well under a second


@dataclass(frozen=True)
class Mutant:
    """One mutated scenario: where it came from, what was done, its bytes."""

    index: int
    base: str
    ops: tuple[str, ...]
    data: bytes


# ---- the mutator -----------------------------------------------------------------------------------------------


def _nodes(tree: Any, path: tuple[Any, ...] = ()) -> Iterator[tuple[tuple[Any, ...], Any]]:
    """Every (path, value) in a parsed tree, the root included."""
    yield path, tree
    if isinstance(tree, dict):
        for k, v in tree.items():
            yield from _nodes(v, (*path, k))
    elif isinstance(tree, list):
        for i, v in enumerate(tree):
            yield from _nodes(v, (*path, i))


def _set(tree: Any, path: tuple[Any, ...], value: Any) -> Any:
    if not path:
        return value
    parent = tree
    for p in path[:-1]:
        parent = parent[p]
    parent[path[-1]] = value
    return tree


def _pick(rng: random.Random, tree: Any, want: type | tuple[type, ...] | None = None) -> tuple[tuple[Any, ...], Any]:
    nodes = [(p, v) for p, v in _nodes(tree) if p and (want is None or isinstance(v, want))]
    if not nodes:
        return (), tree
    return nodes[rng.randrange(len(nodes))]


def _tree_op(rng: random.Random, tree: Any) -> tuple[Any, str]:
    """One tree mutation; returns the tree and a label."""
    kind = rng.choice(("leaf", "leaf", "leaf", "scale", "scale", "delete", "typo", "list", "scalar", "wrap", "world"))
    if kind == "leaf":
        path, _ = _pick(rng, tree, (str, int, float, bool, type(None)))
        value = copy.deepcopy(rng.choice(HOSTILE_VALUES))
        return _set(tree, path, value), f"leaf {_label(path)}={value!r:.20}"
    if kind == "scale":
        path, v = _pick(rng, tree, (int, float))
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            return tree, "scale (no number)"
        factor = rng.choice(SCALES)
        return _set(tree, path, v * factor), f"scale {_label(path)}x{factor:g}"
    if kind == "delete":
        path, _ = _pick(rng, tree)
        parent = tree
        for p in path[:-1]:
            parent = parent[p]
        if path and isinstance(parent, (dict, list)):
            del parent[path[-1]]
        return tree, f"delete {_label(path)}"
    if kind == "typo":
        path, v = _pick(rng, tree, dict)
        target = v if path else tree
        if isinstance(target, dict) and target:
            key = rng.choice(list(target))
            typo = str(key)[:-1] + "x" if len(str(key)) > 1 else "zz"
            target[typo] = target[key]
        return tree, f"typo {_label(path)}"
    if kind == "list":
        path, v = _pick(rng, tree, list)
        if isinstance(v, list):
            if v and rng.random() < 0.5:
                v.append(copy.deepcopy(v[rng.randrange(len(v))]))
            else:
                v.clear()
        return tree, f"list {_label(path)}"
    if kind == "scalar":
        path, _ = _pick(rng, tree, (dict, list))
        return _set(tree, path, rng.choice((0, "x", None, 1e308))), f"scalar {_label(path)}"
    if kind == "wrap":
        path, v = _pick(rng, tree)
        wrapped: Any = v
        for _ in range(60):
            wrapped = [wrapped]
        return _set(tree, path, wrapped), f"wrap {_label(path)}"
    hostile = rng.choice(HOSTILE_PATHS)
    if isinstance(tree, dict):
        tree["world"] = hostile if rng.random() < 0.5 else {"line": hostile}
    return tree, f"world {hostile}"


def _label(path: tuple[Any, ...]) -> str:
    return ".".join(str(p) for p in path) or "<root>"


def _text_op(rng: random.Random, text: str) -> tuple[bytes, str]:
    """One text mutation of the YAML ``text``; returns the bytes and a label."""
    kind = rng.choice(("bomb", "deep", "bigint", "truncate", "punct", "punct", "bytes"))
    if kind == "bomb":
        lines = [ln for ln in text.splitlines() if not ln.startswith("description:")]
        return ("description: " + ALIAS_BOMB + "\n" + "\n".join(lines) + "\n").encode(), "alias bomb"
    if kind == "deep":
        return (text + "\nnested: " + "[" * 5000 + "]" * 5000 + "\n").encode(), "deep nesting"
    if kind == "bigint":
        return text.replace("seed: ", "seed: " + "9" * 5000 + "#", 1).encode(), "5000-digit int"
    if kind == "truncate":
        cut = rng.randrange(len(text) + 1)
        return text[:cut].encode(), f"truncate at {cut}"
    if kind == "punct":
        i = rng.randrange(len(text)) if text else 0
        ch = rng.choice(PUNCTUATION)
        return (text[:i] + ch + text[i + 1 :]).encode(), f"char {i}={ch!r}"
    i = rng.randrange(len(text) + 1)
    return text[:i].encode() + b"\xff\xfe\x80" + text[i:].encode(), f"bytes at {i}"


def mutant(index: int, seed: int = 0, bases: list[Path] | None = None) -> Mutant:
    """Mutant ``index`` of the campaign ``seed`` (deterministic)."""
    bases = bases or SHIPPED
    base = bases[index % len(bases)]
    rng = random.Random(seed * 1_000_003 + index)
    tree = yaml.safe_load(base.read_text(encoding="utf-8"))
    ops: list[str] = []
    for _ in range(rng.choice((1, 1, 2, 3))):
        tree, label = _tree_op(rng, tree)
        ops.append(label)
    text = yaml.safe_dump(tree, sort_keys=False, allow_unicode=True)
    if rng.random() < 0.25:
        data, label = _text_op(rng, text)
        ops.append(label)
    else:
        data = text.encode()
    return Mutant(index, base.name, tuple(ops), data)


def mutants(n: int, seed: int = 0) -> Iterator[Mutant]:
    for k in range(n):
        yield mutant(k, seed)


# ---- running validate in this process ----------------------------------------------------------------------------


class Hang(BaseException):  # noqa: N818 - a BaseException so that main()'s last guard cannot catch it
    """A mutant took longer than its time limit."""


@dataclass
class Outcome:
    rc: int | None  # None: a hang or an escaped exception
    stderr: str
    seconds: float
    problem: str | None = None  # why this outcome breaks the contract (None: fine)


def _on_alarm(signum: int, frame: Any) -> None:
    raise Hang()


def validate_in_process(path: Path, timeout_s: float = TIMEOUT_S, world_check: bool = False) -> Outcome:
    """``railsim validate --no-world-check PATH`` (``world_check``: with the world check) in this process; the
    outcome and whether it keeps the contract (:func:`cli_in_process`)."""
    return cli_in_process(["validate", *([] if world_check else ["--no-world-check"]), str(path)], timeout_s)


def cli_in_process(argv: list[str], timeout_s: float = TIMEOUT_S) -> Outcome:
    """``railsim ARGV`` through :func:`railsim.cli.main.main` in this process, under a time limit; the outcome and
    whether it keeps the contract: exit 0 or 2, and on 2 exactly one line ``railsim: error: ...`` without a
    traceback."""
    from railsim.cli.main import main

    err, out = io.StringIO(), io.StringIO()
    old = signal.signal(signal.SIGALRM, _on_alarm)
    signal.setitimer(signal.ITIMER_REAL, timeout_s)
    t0 = time.perf_counter()
    rc: int | None = None
    problem: str | None = None
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
            rc = main(argv)
    except Hang:
        problem = f"hang (> {timeout_s:g} s)"
    except BaseException as exc:  # noqa: BLE001 - anything escaping main breaks the contract
        problem = f"escaped {type(exc).__name__}: {str(exc)[:200]}"
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
    seconds = time.perf_counter() - t0
    text = err.getvalue()
    if problem is None:
        lines = text.splitlines()
        if rc not in (0, 2):
            problem = f"exit {rc}"
        elif "Traceback" in text:
            problem = "traceback"
        elif rc == 2 and (len(lines) != 1 or not lines[0].startswith("railsim: error: ")):
            problem = f"expected one error line, got {len(lines)}"
        elif rc == 2 and len(lines[0]) > 1200:
            problem = f"error line of {len(lines[0])} characters"
    return Outcome(rc, text, seconds, problem)


@dataclass
class Figures:
    mutants: int = 0
    accepted: int = 0
    rejected: int = 0
    problems: list[str] = field(default_factory=list)
    hangs: int = 0
    tracebacks: int = 0
    seconds: float = 0.0
    slowest_s: float = 0.0
    accepted_files: list[Path] = field(default_factory=list)


def campaign(n: int, workdir: Path, seed: int = 0) -> Figures:
    """Validate ``n`` mutants in process; the figures (``accepted_files`` keeps the accepted mutants on disk)."""
    fig = Figures()
    t0 = time.perf_counter()
    for m in mutants(n, seed):
        path = workdir / f"mutant_{m.index:05d}.yaml"
        path.write_bytes(m.data)
        res = validate_in_process(path)
        fig.mutants += 1
        fig.slowest_s = max(fig.slowest_s, res.seconds)
        if res.problem is not None:
            fig.problems.append(f"mutant {m.index} ({m.base}: {'; '.join(m.ops)}): {res.problem}: {res.stderr[:300]}")
            fig.hangs += res.problem.startswith("hang")
            fig.tracebacks += "Traceback" in res.stderr or res.problem.startswith("escaped")
        if res.rc == 0:
            fig.accepted += 1
            fig.accepted_files.append(path)
        elif res.rc == 2:
            fig.rejected += 1
            path.unlink()
        else:
            path.unlink()
    fig.seconds = time.perf_counter() - t0
    return fig


# ---- short runs of accepted mutants (child processes, real SUMO) -----------------------------------------------------


def short_horizon(path: Path, horizon_s: float = 10.0) -> Path:
    """A copy of the accepted mutant ``path`` whose run ends ``horizon_s`` after its first departure."""
    from railsim import scenario

    scn = scenario.load(path)
    first = min(t for svc in scn.services for t in svc.departures_s)
    data = yaml.safe_load(path.read_text(encoding="utf-8"))
    data["simulation"]["duration_s"] = min(scn.simulation.duration_s, first + horizon_s)
    out = path.with_name(path.stem + "_short.yaml")
    out.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return out


def non_finite_cells(out_dir: Path) -> list[str]:
    """``file: value`` for every NaN or infinite number in a run's CSV and JSON outputs."""
    bad: list[str] = []
    for f in sorted(out_dir.glob("*.csv")):
        for line_no, line in enumerate(f.read_text(encoding="utf-8").splitlines()):
            for cell in line.split(","):
                if cell.strip().lower() in ("nan", "inf", "-inf", "+inf", "infinity", "-infinity"):
                    bad.append(f"{f.name}:{line_no + 1}: {cell}")
    for f in sorted(out_dir.glob("*.json")):
        text = f.read_text(encoding="utf-8")
        for token in ("NaN", "Infinity"):
            if token in text:
                bad.append(f"{f.name}: {token}")
        json.loads(text)
    return bad


def campaign_parser(description: str, mutants: int, first: bool = False) -> argparse.ArgumentParser:
    """The options every fuzzer's command line shares: how many mutants, the seed, and (``first``) the index of the
    first mutant, so a campaign can be resumed or one mutant replayed."""
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("--mutants", type=int, default=mutants)
    if first:
        ap.add_argument("--first", type=int, default=0, help="index of the first mutant")
    ap.add_argument("--seed", type=int, default=0)
    return ap


def main(argv: list[str] | None = None) -> int:
    import tempfile

    from tests.helpers import run_railsim

    ap = campaign_parser("Fuzz railsim validate (and run) with mutants of the shipped scenarios.", 1000)
    ap.add_argument("--runs", type=int, default=0, help="run this many accepted mutants (evenly spread; -1: all)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="railsim-fuzz-") as tmp:
        fig = campaign(args.mutants, Path(tmp), args.seed)
        print(
            f"mutants {fig.mutants}, accepted {fig.accepted}, rejected {fig.rejected}, problems {len(fig.problems)} "
            f"(hangs {fig.hangs}, tracebacks {fig.tracebacks}); {fig.seconds:.1f} s, slowest {fig.slowest_s:.2f} s"
        )
        for p in fig.problems:
            print("  " + p)
        picked = sample(fig.accepted_files, len(fig.accepted_files) if args.runs < 0 else args.runs)
        codes: dict[int, int] = {}
        world_rejected = 0
        run_problems = 0
        for path in picked:
            short = short_horizon(path)
            res = run_railsim(["validate", str(short)], timeout=600)  # the world check: stations, routes, ...
            if res.returncode != 0:
                world_rejected += 1
                if res.returncode != 2 or not one_error_line(res.stderr):
                    print(f"  validate {path.name}: exit {res.returncode} {res.stderr.strip()[-300:]}")
                continue
            res = run_railsim(["run", str(short), "--out", str(short.with_suffix("")), "--no-progress"], timeout=600)
            codes[res.returncode] = codes.get(res.returncode, 0) + 1
            bad = non_finite_cells(short.with_suffix("")) if short.with_suffix("").is_dir() else []
            if res.returncode not in (0, 1, 3) or bad or "Traceback" in res.stderr:
                run_problems += 1
                print(f"  run {path.name}: exit {res.returncode} {bad[:3]} {res.stderr.strip()[-300:]}")
        if picked:
            print(
                f"picked {len(picked)}: refused by the world check {world_rejected}, runs {sum(codes.values())}: "
                f"exit codes {dict(sorted(codes.items()))}"
            )
    return 1 if fig.problems or run_problems else 0


def one_error_line(stderr: str) -> bool:
    """Exactly one ``railsim: error:`` line and no traceback (log warnings before it are fine)."""
    errors = [ln for ln in stderr.splitlines() if ln.startswith("railsim: error: ")]
    return len(errors) == 1 and "Traceback" not in stderr


def sample(items: list[Path], n: int) -> list[Path]:
    """``n`` of ``items`` spread evenly (deterministic)."""
    if n <= 0 or not items:
        return []
    if n >= len(items):
        return list(items)
    return [items[int(i * len(items) / n)] for i in range(n)]


if __name__ == "__main__":
    sys.exit(main())
