"""Which Python the bootstrap builds ``.venv`` with: the fastest build of the default ``python3``'s version.

railsim spends most of a run in its own interpreted Python (per train and step: situation, locks, stops, the call
into the compiled step), so how the interpreter itself was built matters as much as any change to the engine. Two
CPython builds of the same version can differ by a factor of two on such code. A build made by ``pyenv`` or
``./configure && make`` without ``--enable-optimizations`` and with ``--enable-shared`` has no profile-guided
optimization, and every call into the interpreter's core goes through its shared library's symbol table; the
distributions' and python.org's builds are profile-guided and link the core into the executable. On the machines
this project is developed on, the default ``python3`` is such a plain pyenv build (3.11.7) and Debian's
``/usr/bin/python3.11`` (3.11.2) an optimized one: 2.2× faster on the probe below, ~10 % less CPU on the demo and
the Line 3 day (much of a step is SUMO, libsumo, numpy and compiled kernels; docs/performance.md, "The
interpreter").

The rule, run by ``make`` before it makes ``.venv`` (and only then: an existing ``.venv`` is kept; ``make clean``
drops it; ``make PY=/path/to/python`` chooses yourself)::

    python3 railsim/interpreter.py      # prints the interpreter to build .venv with

1. Candidates: the default ``python3`` and the other usual names of the same minor version on this machine
   (``python3.X`` on the ``PATH``, ``/usr/bin``, ``/usr/local/bin``), each counted once (by its real executable).
   Only the default's version is considered: ``constraints.txt`` is pinned and tested for it.
2. A candidate must be able to make a virtual environment with pip (``venv`` and ``ensurepip`` importable).
3. Each one times the same small pure-Python workload (objects, attribute reads, a dict, float arithmetic: the
   engine's kind of work), best of five runs of its process CPU time.
4. The fastest wins if it is at least :data:`MIN_GAIN` faster than the default; otherwise the default is kept (a
   choice between two builds that differ by noise would flip from one clone to the next).

The choice and the timings go to stderr; stdout carries only the path. Any failure of a candidate (missing, too old,
a timeout) just drops it; if nothing else qualifies, the default ``python3`` is printed. The railsim outputs do not
depend on the choice: the same seed gives the same bytes under every build (the golden tier passes under both).

This file runs on the bare machine, before anything is installed: the standard library only, and nothing from
railsim (it is run by path, so the package is not imported).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys

DEFAULT = "python3"
MIN_GAIN = 1.10  # the fastest must beat the default by 10 % to be chosen
TIMEOUT_S = 60.0
FOLDERS = ("/usr/bin", "/usr/local/bin")  # where a system's builds live, beside the PATH

# Run inside each candidate: can it make a venv with pip, its real executable and version, then the best of five
# CPU timings of the workload. Printed as one line: "<executable> <major.minor> <seconds>".
PROBE = r"""
import os, sys, time
import venv, ensurepip  # noqa: F401 (a venv with pip must be possible)

class Body:
    def __init__(self, front_m, length_m):
        self.front_m = front_m
        self.length_m = length_m

def work(n):
    seen = {}
    acc = 0.0
    for i in range(n):
        b = Body(i * 0.5, 120.0)
        seen[i & 1023] = b
        rear_m = b.front_m - b.length_m
        acc += rear_m if i & 1 else -rear_m
        acc = acc * 0.999 if acc > 0.0 else acc
    return acc

best = float("inf")
for _ in range(5):
    c0 = time.process_time()
    work(100_000)
    best = min(best, time.process_time() - c0)
print(os.path.realpath(sys.executable), "%d.%d" % sys.version_info[:2], repr(best))
"""


def probe(python: str) -> tuple[str, str, float] | None:
    """``(real executable, "major.minor", best CPU seconds)`` of ``python``, or None if it cannot be used."""
    try:
        out = subprocess.run(
            [python, "-I", "-c", PROBE], capture_output=True, text=True, timeout=TIMEOUT_S, check=True
        ).stdout.split()
        return out[0], out[1], float(out[2])
    except (OSError, subprocess.SubprocessError, IndexError, ValueError):
        return None


def candidates(version: str, probed: set[str]) -> list[str]:
    """The names and paths a build of ``version`` ("3.11") usually has on this machine, each once and none whose
    file is in ``probed`` (real paths already timed: the default's command and executable)."""
    paths = [shutil.which(f"python{version}")]
    for folder in FOLDERS:
        paths += [os.path.join(folder, f"python{version}"), os.path.join(folder, "python3")]
    seen = set(probed)
    found = []
    for p in paths:
        if p and os.path.isfile(p) and os.access(p, os.X_OK) and os.path.realpath(p) not in seen:
            seen.add(os.path.realpath(p))
            found.append(p)
    return found


def choose() -> str:
    """The interpreter to build ``.venv`` with (module docstring)."""
    default_path = shutil.which(DEFAULT)
    default = probe(DEFAULT) if default_path else None
    if default_path is None or default is None:
        print(f"bootstrap: {DEFAULT} cannot make a venv with pip; using it anyway", file=sys.stderr)
        return DEFAULT
    real, version, best_s = default
    timed = {real: (DEFAULT, best_s)}
    for path in candidates(version, {real, os.path.realpath(default_path)}):
        got = probe(path)
        if got is None or got[1] != version or got[0] in timed:
            continue
        timed[got[0]] = (path, got[2])
    fastest = min(timed, key=lambda r: timed[r][1])
    gain = best_s / timed[fastest][1]
    for r, (name, s) in sorted(timed.items(), key=lambda kv: kv[1][1]):
        print(f"bootstrap: Python {version} at {r} ({name}): {s * 1e3:.0f} ms on the probe", file=sys.stderr)
    if fastest == real or gain < MIN_GAIN:
        print(f"bootstrap: building .venv with {DEFAULT} ({real})", file=sys.stderr)
        return DEFAULT
    print(
        f"bootstrap: building .venv with {fastest}: {gain:.2f}x faster than {DEFAULT} ({real}) on interpreted code",
        file=sys.stderr,
    )
    return fastest


if __name__ == "__main__":
    print(choose())
