"""Golden outputs: fixed-seed runs whose every output file must stay byte-identical across refactors.

The golden set covers the default demo (Line 3 peak hour), one scenario of every paper family (A–E) and one
scenario on a SUMO net railsim did not generate (the passing-loop net of ``tests/sumo/test_external_net.py``). Each
case runs ``railsim run`` in a child process; its output folder is *normalised* and hashed file by file:

* wall-clock fields are dropped — JSON keys and CSV columns whose name contains ``wall`` or ``solve_time``
  (controller solve times, planner wall times, the run's wall time), also inside the JSON ``detail`` column of
  ``events.csv``;
* the case's temporary folder is replaced by ``<TMP>`` (an external net's path appears in the resolved scenario),
  and an external net's cache key in ``sumo_run.sumocfg`` by ``<HASH>`` (it hashes netconvert's header, which names
  the temporary folder).

Everything else — every number in ``trips.csv``, ``stops.csv``, ``formations.csv``, ``events.csv``,
``trace.csv``, ``summary.json``, ``scenario.resolved.yaml``, ``versions.json`` — is compared as bytes.

The hashes live in ``tests/data/golden.json``. A change that is *meant* to alter outputs regenerates them::

    .venv/bin/python -m tests.golden --update          # rewrites tests/data/golden.json
    .venv/bin/python -m tests.golden --keep DIR        # also keeps the normalised outputs for a diff
    .venv/bin/python -m tests.golden --case paper001_sempc --record-variant "CPU, cores, BLAS"
                                                       # records this machine's BLAS outcome of a case

and says why in its commit message (docs/architecture.md, "The golden test").
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import io
import json
import re
import sys
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from tests.helpers import ROOT, run_railsim

GOLDEN_FILE = ROOT / "tests" / "data" / "golden.json"
# Cases whose outputs depend on the machine's BLAS (OpenBLAS picks its kernels by CPU type and splits a product over
# the cores): the model-predictive controllers multiply and factor matrices of a few hundred entries, and another
# kernel or split rounds the last bits differently. This file holds, per case, the other outcomes recorded on real
# machines (each with the machine it was seen on); ``accepted`` takes any of them. A code change that alters outputs
# changes every one of them, so it still fails.
BLAS_VARIANTS_FILE = ROOT / "tests" / "data" / "golden_blas_variants.json"
WALL_CLOCK = re.compile(r"wall|solve_time")


@dataclass(frozen=True)
class Case:
    """One golden run: a scenario file (or a builder that writes one into a folder) and its seed."""

    name: str
    scenario: str | Callable[[Path], Path]
    seed: int = 7


def _external_passing_loop(folder: Path) -> Path:
    from tests.sumo.test_external_net import _scenario, build_passing_loop

    net, stops = build_passing_loop(folder)
    return _scenario(folder, "passing", net, stops)


CASES: tuple[Case, ...] = (
    Case("demo_line3_peak", "scenarios/chongqing_line3_peak.yaml"),
    Case("paper000_dmpc", "scenarios/paper000_sd_comparison_dmpc.yaml"),
    Case("paper001_sempc", "scenarios/paper001_single_section.yaml"),
    Case("paper002_distributed", "scenarios/paper002_topology_switch.yaml"),
    Case("paper003_monorail", "scenarios/paper003_track_accel.yaml"),
    Case("paper004_junction", "scenarios/paper004_table3_s1.yaml"),
    Case("external_passing_loop", _external_passing_loop),
)


def _drop_wall(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _drop_wall(v) for k, v in value.items() if not WALL_CLOCK.search(k)}
    if isinstance(value, list):
        return [_drop_wall(v) for v in value]
    return value


def _normalise_csv(text: str) -> str:
    rows = list(csv.reader(io.StringIO(text)))
    if not rows:
        return text
    keep = [i for i, col in enumerate(rows[0]) if not WALL_CLOCK.search(col)]
    detail = rows[0].index("detail") if "detail" in rows[0] else -1
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    for n, row in enumerate(rows):
        if n and detail >= 0 and row[detail].startswith("{"):
            row[detail] = json.dumps(_drop_wall(json.loads(row[detail])), sort_keys=True, separators=(",", ":"))
        writer.writerow([row[i] for i in keep])
    return out.getvalue()


def normalise(path: Path, tmp_root: Path) -> bytes:
    """The file's bytes with wall-clock fields removed and the case's temporary folder replaced."""
    text = path.read_text(encoding="utf-8").replace(str(tmp_root), "<TMP>")
    if path.suffix == ".sumocfg":  # an external net's cache key hashes netconvert's header, which names <TMP>
        text = re.sub(r"external-[0-9a-f]+", "external-<HASH>", text)
    if path.suffix == ".json":
        text = json.dumps(_drop_wall(json.loads(text)), indent=2, sort_keys=True) + "\n"
    elif path.suffix == ".csv":
        text = _normalise_csv(text)
    return text.encode("utf-8")


def run_outputs(case: Case, workdir: Path, reference: bool = False) -> int:
    """Run one case in a child process, its outputs into ``workdir/out``; return its exit code. ``reference``: on
    railsim's interpreted modules instead of the compiled core (:mod:`railsim.native`)."""
    workdir.mkdir(parents=True, exist_ok=True)
    scenario = case.scenario(workdir) if callable(case.scenario) else ROOT / case.scenario
    out = workdir / "out"
    res = run_railsim(
        ["run", str(scenario), "--out", str(out), "--seed", str(case.seed), "--no-progress"],
        cache_dir=workdir / "cache",
        timeout=900,
        reference=reference,
    )
    if res.returncode not in (0, 1) or "Traceback" in res.stderr or not (out / "summary.json").is_file():
        raise RuntimeError(f"golden case {case.name} failed (exit {res.returncode}):\n{res.stderr[-3000:]}")
    return res.returncode


def hash_outputs(name: str, workdir: Path, exit_code: int, keep: Path | None = None) -> dict[str, str]:
    """{file name: sha256 of its normalised bytes} of the outputs in ``workdir/out``, and the run's exit code."""
    hashes: dict[str, str] = {"exit_code": str(exit_code)}
    for path in sorted(p for p in (workdir / "out").iterdir() if p.is_file()):
        data = normalise(path, workdir)
        hashes[path.name] = hashlib.sha256(data).hexdigest()
        if keep is not None:
            (keep / name).mkdir(parents=True, exist_ok=True)
            (keep / name / path.name).write_bytes(data)
    return hashes


def run_case(case: Case, workdir: Path, keep: Path | None = None) -> dict[str, str]:
    """Run one case in a child process; return {file name: sha256 of its normalised bytes}."""
    return hash_outputs(case.name, workdir, run_outputs(case, workdir), keep)


def load_golden() -> dict[str, dict[str, str]]:
    return json.loads(GOLDEN_FILE.read_text(encoding="utf-8"))


def blas_variants() -> dict[str, list[dict[str, Any]]]:
    """Per case, its outcomes recorded on other machines: ``{"hashes": {...}, "machine": "..."}`` each."""
    return json.loads(BLAS_VARIANTS_FILE.read_text(encoding="utf-8")) if BLAS_VARIANTS_FILE.exists() else {}


def accepted(name: str) -> list[dict[str, str]]:
    """The hashes a case may give: ``golden.json``'s, then the BLAS variants recorded for it (``BLAS_VARIANTS_FILE``)."""
    return [load_golden()[name], *(v["hashes"] for v in blas_variants().get(name, []))]


def differing(got: dict[str, str], expected: dict[str, str]) -> list[str]:
    """The files whose hashes differ between two outcomes of a case (one missing on either side counts)."""
    return sorted(k for k in set(got) | set(expected) if got.get(k) != expected.get(k))


def record_variant(name: str, hashes: dict[str, str], machine: str) -> bool:
    """Add ``hashes`` to ``name``'s recorded BLAS outcomes, seen on ``machine`` (docs/architecture.md, "The golden
    test"); False if they are golden.json's or already recorded."""
    if hashes in accepted(name):
        return False
    variants = blas_variants()
    variants.setdefault(name, []).append({"hashes": hashes, "machine": machine})
    BLAS_VARIANTS_FILE.write_text(json.dumps(variants, indent=2, sort_keys=True) + "\n", encoding="utf-8")
    return True


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="run the golden cases; compare with or update tests/data/golden.json")
    parser.add_argument("--update", action="store_true", help="rewrite tests/data/golden.json")
    parser.add_argument("--keep", type=Path, default=None, help="keep the normalised outputs in this folder")
    parser.add_argument("--case", action="append", default=None, help="only these cases (repeatable)")
    parser.add_argument(
        "--record-variant",
        metavar="MACHINE",
        default=None,
        help="record the named --case's outcome as a BLAS variant seen on MACHINE (only a BLAS-dependent case)",
    )
    args = parser.parse_args(argv)
    if args.record_variant is not None and (not args.case or args.update):
        parser.error("--record-variant needs --case (the BLAS-dependent cases) and no --update")
    golden = load_golden() if GOLDEN_FILE.exists() else {}
    differ = 0
    with tempfile.TemporaryDirectory(prefix="railsim-golden-") as tmp:
        for case in CASES:
            if args.case and case.name not in args.case:
                continue
            got = run_case(case, Path(tmp) / case.name, args.keep)
            bad = differing(got, golden.get(case.name, {}))
            if bad and case.name in golden and got in accepted(case.name)[1:]:
                print(f"{case.name}: same as a recorded BLAS variant ({BLAS_VARIANTS_FILE.name})")
                continue
            if bad and case.name in golden and args.record_variant is not None:
                record_variant(case.name, got, args.record_variant)
                print(f"{case.name}: recorded in {BLAS_VARIANTS_FILE.name} as seen on {args.record_variant}")
                continue
            print(f"{case.name}: {'same' if not bad else 'DIFFERS in ' + ', '.join(bad)}")
            differ += bool(bad)
            golden[case.name] = got
    if args.update:
        GOLDEN_FILE.write_text(json.dumps(golden, indent=2, sort_keys=True) + "\n", encoding="utf-8")
        print(f"wrote {GOLDEN_FILE}")
        return 0
    return 1 if differ else 0


if __name__ == "__main__":
    sys.exit(main())
