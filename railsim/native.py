"""The compiled core: the step loop's modules compiled to C with mypyc, loaded when built and up to date.

Most of a railsim step is Python over objects — a few hundred attribute reads, calls and small tuples per train
and step, spread over some twenty functions (docs/performance.md, "Where the time goes"). mypyc, the compiler that
ships with mypy (which already type-checks this code), turns type-annotated modules into C extension modules:
calls between compiled functions are C calls, the fields of compiled classes are C struct fields, arithmetic on
annotated ``float`` and ``int`` locals is unboxed. Nothing is written twice: the compiled module *is* its source,
and the interpreted module stays the readable reference (the unit tier runs it in-process; every SUMO run of the
suite, the golden tier included, runs in a child process on the compiled core and must give the same bytes).

What is compiled: :data:`MODULES` — the loop, the control stage and the trains' situations, the train's state and the
plant, the truth pass, occupancy, stops, berths, comms (and its messages in flight), the event clock and log, safety,
the watchdog, recording, the SUMO bridge, the route locks (their switch walk and authority ends are mypyc *traits*,
the parts a class may have besides its one base class), the single-track sections and crossings, the interlocking,
formations, the trips, the engine's settings, the scenario's disturbances and the vehicle's parameters. Their classes
become *native*: their attributes are the annotated ones (none can be added at run time), their methods cannot be
patched, an interpreted subclass needs ``@mypyc_attr(allow_interpreted_subclasses=True)``, and a value of the wrong
type handed to an annotated parameter raises :class:`TypeError` instead of being duck-typed (an ``int`` given for a
``float`` becomes a ``float``). A dataclass keeps its generated methods interpreted (write a hot constructor out), its
fields' ``type`` is the class rather than its name, and a frozen one unpickles only through ``__reduce__`` (a
constructor call).

Build: ``python -m railsim.compile_core`` (``make native``; ``make demo`` and ``make test`` call it) compiles them
into ``build/native/`` and writes a stamp with the hash of their sources and the interpreter's version; with
``--if-stale`` it does nothing when the stamp already matches; ``--status`` says what this interpreter loads. About
three minutes of one core; it needs a C compiler and the Python headers (a machine without them runs interpreted).

Use: importing :mod:`railsim` calls :func:`activate`, which puts a finder in front of the import system that loads
those modules from ``build/native/`` when the stamp matches the sources in the tree. Otherwise — never built, a
source edited since, another interpreter — the interpreted modules load, and a build that is there but out of date
says so once on stderr when the first of them is imported (the build itself, which imports none, says nothing).
``RAILSIM_NATIVE=0`` asks for the interpreted modules. :data:`STATUS` says which ran.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib.abc
import importlib.machinery
import importlib.util
import json
import os
import shutil
import sys
import sysconfig
import time
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType

MODULES: tuple[str, ...] = (
    "railsim.physics.dynamics",
    "railsim.engine.train",
    "railsim.engine.control",
    "railsim.engine.situation",
    "railsim.engine.stops",
    "railsim.engine.knowledge",
    "railsim.engine.events.comms",
    "railsim.engine.events.in_flight",
    "railsim.engine.events.clock",
    "railsim.engine.occupancy",
    "railsim.engine.truth",
    "railsim.engine.loop",
    "railsim.engine.fleet",
    "railsim.engine.platforms",
    "railsim.engine.safety",
    "railsim.engine.watchdog",
    "railsim.engine.recording",
    "railsim.engine.sumo",
    "railsim.engine.slots",
    "railsim.engine.routeview",
    "railsim.engine.locking",
    "railsim.engine.lock_walk",
    "railsim.engine.section_requests",
    "railsim.engine.terminus_room",
    "railsim.engine.section_room",
    "railsim.engine.section_walk",
    "railsim.engine.authority",
    "railsim.engine.events.tracks",
    "railsim.engine.events.interlocking",
    "railsim.engine.events.log",
    "railsim.engine.single_track",
    "railsim.engine.stop_timing",
    "railsim.engine.trips",
    "railsim.engine.coupling",
    "railsim.engine.insertion_reach",
    "railsim.engine.settings",
    "railsim.engine.disturbances",
    "railsim.physics.vehicle",
    "railsim.engine.events.formations",
)
ROOT = Path(__file__).resolve().parent.parent
BUILD_DIR = ROOT / "build" / "native"
STAMP_FILE = "stamp.json"
ENV = "RAILSIM_NATIVE"

STATUS = "interpreted (not activated)"  # set by activate(): "compiled (N modules)" or why not


def source_of(module: str) -> Path:
    """The source file of a dotted module name of this repository."""
    return ROOT.joinpath(*module.split(".")).with_suffix(".py")


def fingerprint() -> dict[str, str]:
    """What a build is valid for: the hash of the compiled modules' sources (names and bytes) and the interpreter."""
    digest = hashlib.sha256()
    for module in MODULES:
        digest.update(module.encode() + b"\0" + source_of(module).read_bytes() + b"\0")
    return {
        "sources_sha256": digest.hexdigest(),
        "python": sys.version,
        "ext_suffix": str(sysconfig.get_config_var("EXT_SUFFIX")),
    }


def _stamp(build_dir: Path) -> dict[str, str] | None:
    try:
        data = json.loads((build_dir / STAMP_FILE).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def _extension_files(build_dir: Path) -> dict[str, Path] | None:
    """Module name -> extension file in ``build_dir``: every module of :data:`MODULES` and mypyc's shared library
    (a top-level ``<hash>__mypyc`` module the others import); None when one is missing."""
    suffix = str(sysconfig.get_config_var("EXT_SUFFIX"))
    files = {m: build_dir.joinpath(*m.split(".")).with_name(m.rsplit(".", 1)[1] + suffix) for m in MODULES}
    for lib in build_dir.glob("*__mypyc" + suffix):
        files[lib.name[: -len(suffix)]] = lib
    if not all(f.is_file() for f in files.values()) or len(files) == len(MODULES):
        return None
    return files


class _NativeFinder(importlib.abc.MetaPathFinder):
    """Finds the compiled modules (and only those) in the build folder."""

    def __init__(self, files: dict[str, Path]) -> None:
        self.files = files

    def find_spec(
        self, fullname: str, path: Sequence[str] | None, target: ModuleType | None = None
    ) -> importlib.machinery.ModuleSpec | None:
        file = self.files.get(fullname)
        if file is None:
            return None
        loader = importlib.machinery.ExtensionFileLoader(fullname, str(file))
        return importlib.util.spec_from_file_location(fullname, file, loader=loader)


def activate(build_dir: Path = BUILD_DIR) -> str:
    """Load the compiled modules from ``build_dir`` from now on if the build matches the sources (module
    docstring); returns and sets :data:`STATUS`. Call it before any of :data:`MODULES` is imported."""
    global STATUS
    if any(isinstance(f, (_NativeFinder, _StaleNotice)) for f in sys.meta_path):
        return STATUS
    STATUS, finder = _activate(build_dir)
    if finder is not None:
        sys.meta_path.insert(0, finder)
    return STATUS


def _activate(build_dir: Path) -> tuple[str, importlib.abc.MetaPathFinder | None]:
    """The status, and the finder to put in front of the import system: the compiled modules', or the notice
    that the build is out of date."""
    if os.environ.get(ENV, "1") == "0":
        return f"interpreted ({ENV}=0)", None
    stamp = _stamp(build_dir)
    if stamp is None:
        return "interpreted (the compiled core is not built: make native)", None
    try:
        current = fingerprint()
    except OSError as exc:  # an installed copy without its sources: nothing to compare with
        return f"interpreted (sources unreadable: {exc})", None
    if {k: stamp.get(k) for k in current} != current:
        what = "interpreter" if stamp.get("sources_sha256") == current["sources_sha256"] else "sources"
        notice = _StaleNotice(
            f"railsim: the compiled core in {build_dir} was built for other {what}; running interpreted "
            "(make native rebuilds it)"
        )
        return f"interpreted (the compiled core is out of date: other {what})", notice
    files = _extension_files(build_dir)
    if files is None:
        return "interpreted (the compiled core's build folder is incomplete: make native)", None
    loaded = [m for m in MODULES if m in sys.modules]
    if loaded:
        return f"interpreted ({', '.join(loaded)} imported before railsim.native.activate)", None
    return f"compiled ({len(MODULES)} modules, {build_dir})", _NativeFinder(files)


class _StaleNotice(importlib.abc.MetaPathFinder):
    """Says once on stderr that the build is out of date, when the first of :data:`MODULES` is imported: the build
    itself, which imports none of them, says nothing. Finds nothing itself."""

    def __init__(self, message: str) -> None:
        self.message: str | None = message

    def find_spec(
        self, fullname: str, path: Sequence[str] | None, target: ModuleType | None = None
    ) -> importlib.machinery.ModuleSpec | None:
        if self.message is not None and fullname in MODULES:
            print(self.message, file=sys.stderr)
            self.message = None
        return None


# --------------------------------------------------------------------------------------------------- the build


def build(build_dir: Path = BUILD_DIR, if_stale: bool = False) -> int:
    """Compile :data:`MODULES` into ``build_dir`` (replaced whole once the new build is complete); 0 on success,
    1 when the compiler failed (its output in ``build_dir``'s sibling ``native.log``)."""
    want = fingerprint()
    stamp = _stamp(build_dir)
    if if_stale and stamp is not None and {k: stamp.get(k) for k in want} == want and _extension_files(build_dir):
        print(f"railsim: the compiled core is up to date ({build_dir})")
        return 0
    work = build_dir.with_name(build_dir.name + ".work")
    log_file = build_dir.with_name(build_dir.name + ".log")
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    print(
        f"railsim: compiling the engine core with mypyc: {len(MODULES)} modules, a few minutes (log: {log_file})",
        flush=True,
    )
    t0 = time.monotonic()
    ok = _compile(work, log_file)
    if not ok:
        print(f"railsim: could not compile the engine core (see {log_file}); railsim runs interpreted", file=sys.stderr)
        shutil.rmtree(work, ignore_errors=True)
        return 1
    out = work / "lib"
    import mypy.version

    (out / STAMP_FILE).write_text(
        json.dumps({**want, "mypy": mypy.version.__version__}, indent=2, sort_keys=True) + "\n", encoding="utf-8"
    )
    old = build_dir.with_name(build_dir.name + ".old")
    shutil.rmtree(old, ignore_errors=True)
    if build_dir.exists():
        build_dir.rename(old)
    out.rename(build_dir)
    shutil.rmtree(old, ignore_errors=True)
    shutil.rmtree(work, ignore_errors=True)
    print(f"railsim: compiled the engine core in {time.monotonic() - t0:.0f} s ({build_dir})")
    return 0


def _compile(work: Path, log_file: Path) -> bool:
    """mypyc's C for :data:`MODULES`, then the C compiler through setuptools, into ``work/lib``; the output of
    both goes to ``log_file``."""
    sources = [str(source_of(m).relative_to(ROOT)) for m in MODULES]
    with log_file.open("w", encoding="utf-8") as log, contextlib.redirect_stdout(log), contextlib.redirect_stderr(log):
        cwd = os.getcwd()
        os.chdir(ROOT)  # mypyc names modules by their paths relative to the working folder
        try:
            from mypyc.build import mypycify
            from setuptools import setup

            extensions = mypycify(sources, opt_level="3", target_dir=str(work / "c"))
            setup(
                name="railsim-native",
                ext_modules=extensions,
                script_args=["build_ext", "--build-lib", str(work / "lib"), "--build-temp", str(work / "obj")],
            )
        except (Exception, SystemExit) as exc:  # mypyc's type errors, the compiler's: all in the log
            print(f"build failed: {exc!r}", file=log)
            return False
        finally:
            os.chdir(cwd)
    return True
