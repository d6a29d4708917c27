"""One run per folder, written as a whole: a lock, a staging folder, a manifest, and readers that follow it.

A run folder (``railsim run --out DIR``, a sweep's kept case, a study's run) must hold the files of exactly one
run. Three mechanisms make it so:

1. **A lock beside the folder** (:func:`locked`): ``.<name>.lock`` next to ``DIR`` holds the pid of the run writing
   ``DIR`` and an exclusive ``flock`` on it. A second run into the same folder is refused with one line naming that
   pid (:class:`RunFolderError`, exit 3). The kernel drops a ``flock`` when its process dies, so the lock of a killed
   run is stale the moment it dies and the next run takes it over without asking.
2. **A staging folder** (:class:`Staging`): the run writes every file into ``.<name>.staging-<pid>`` next to
   ``DIR``; only when it is done (completed, failed with its outputs written, or interrupted with its tables up to
   the time reached) are its files moved into ``DIR`` (:meth:`Staging.commit`). ``DIR`` that did not exist is the
   staging folder renamed (one atomic step); an existing ``DIR`` first loses its manifest, then every file of the
   previous run it lists (or, without a manifest, every file name a run writes) and the report and export made
   from it (:data:`DERIVED`), then gets this run's files and last this run's manifest. A run that cannot finish writing (a full disk, a file-size limit) discards its
   staging folder and leaves ``DIR`` as it was.
3. **A manifest** (:data:`MANIFEST_PATH`, ``DIR/.railsim/manifest.json``): this run's status and, per file, its
   name, size in bytes and SHA-256. It sits in a sub-folder so that the run's own files (``summary.json``
   included) keep the bytes they have always had. Readers (:func:`member`) take a file only if the manifest lists
   it with the size on disk, so a file left by an earlier run, or one added by hand, is never read as this run's.
   A folder without a manifest (written before manifests existed) is read as it is.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import hashlib
import json
import os
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from railsim.errors import RunFolderError
from railsim.record import output
from railsim.record.snapshot import OUTPUT_FILES

MANIFEST_DIR = ".railsim"
MANIFEST_PATH = f"{MANIFEST_DIR}/manifest.json"
MANIFEST_FORMAT = 1
# file names a run writes besides OUTPUT_FILES (tables some runs have; SUMO's own outputs): cleared from a folder
# without a manifest before a new run's files go in
_EXTRA_STEMS = ("delays",)
_SUMO_OUTPUT_PREFIX = "sumo_"
# what ``railsim report`` and ``railsim export`` write into a run folder by default: they describe the run they
# were made from, so they go with it when a new run replaces the folder
DERIVED = ("report.md", "report.html", "report_figures", "export")


def lock_path(out: Path) -> Path:
    """The lock file of run folder ``out``: ``.<name>.lock`` beside it."""
    return out.parent / f".{out.name}.lock"


def staging_path(out: Path) -> Path:
    """The staging folder of this process's run into ``out``."""
    return out.parent / f".{out.name}.staging-{os.getpid()}"


def os_reason(err: OSError) -> str:
    """The OS's words for ``err`` (``No space left on device``), never a traceback."""
    return err.strerror or (os.strerror(err.errno) if err.errno else type(err).__name__)


@contextlib.contextmanager
def locked(out: Path) -> Iterator[Path]:
    """Hold the lock of run folder ``out`` for the block (module docstring, 1); yields the lock file's path.

    Raises :class:`RunFolderError` naming the holder's pid if another live process holds it.
    """
    out = Path(out)
    path = lock_path(out)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        while True:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = os.pread(fd, 32, 0).decode("ascii", "replace").strip() or "unknown"
                os.close(fd)
                raise RunFolderError(
                    f"{out}: in use by another railsim run (pid {holder[:20]}, lock file {path}); "
                    "wait for it to end or choose another --out"
                ) from None
            try:
                same = os.fstat(fd).st_ino == os.stat(path).st_ino
            except FileNotFoundError:  # the previous holder removed it between our open and our flock
                same = False
            if same:
                break
            os.close(fd)
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode("ascii"), 0)
    except OSError as err:
        raise RunFolderError(f"{path}: cannot lock the run folder: {os_reason(err)}") from None
    try:
        yield path
    finally:
        with contextlib.suppress(OSError):
            os.unlink(path)
        os.close(fd)


def file_entries(folder: Path) -> list[dict[str, Any]]:
    """``{name, bytes, sha256}`` of every regular file under ``folder`` (sub-folders too, the manifest's aside)."""
    entries = []
    for path in sorted(p for p in Path(folder).rglob("*") if p.is_file() and not p.is_symlink()):
        rel = path.relative_to(folder).as_posix()
        if rel.split("/", 1)[0] == MANIFEST_DIR:
            continue
        digest = hashlib.sha256()
        with path.open("rb") as fh:
            for block in iter(lambda: fh.read(1 << 20), b""):
                digest.update(block)
        entries.append({"name": rel, "bytes": path.stat().st_size, "sha256": digest.hexdigest()})
    return entries


def read_manifest(folder: Path) -> dict[str, Any] | None:
    """The manifest of run folder ``folder``, or None if it has none (or an unreadable one)."""
    try:
        data = json.loads((Path(folder) / MANIFEST_PATH).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) and isinstance(data.get("files"), list) else None


def member(folder: Path | str, name: str) -> Path | None:
    """``folder/name`` if it is this run's file: listed in the manifest with its size on disk; None otherwise.

    A folder without a manifest is taken as it is (the file if it exists).
    """
    path = Path(folder) / name
    manifest = read_manifest(Path(folder))
    if manifest is None:
        return path if path.is_file() else None
    for entry in manifest["files"]:
        if isinstance(entry, dict) and entry.get("name") == name:
            try:
                return path if path.is_file() and path.stat().st_size == entry.get("bytes") else None
            except OSError:
                return None
    return None


def _previous_files(out: Path) -> list[str]:
    """The files of the run already in ``out``: its manifest's list, or every name a run writes."""
    manifest = read_manifest(out)
    if manifest is not None:
        return [str(e["name"]) for e in manifest["files"] if isinstance(e, dict) and "name" in e]
    stems = [f.stem for f in OUTPUT_FILES if f.kind == "table"] + list(_EXTRA_STEMS)
    names = {f.file_name for f in OUTPUT_FILES} | {f"{s}.{ext}" for s in stems for ext in ("csv", "parquet")}
    names |= {p.name for p in out.glob(f"{_SUMO_OUTPUT_PREFIX}*.xml")}
    return sorted(names)


class Staging:
    """The staging folder of one run into ``out`` (module docstring, 2). Use :func:`writing`."""

    def __init__(self, out: Path) -> None:
        self.out = Path(out)
        self.path = staging_path(self.out)
        self.committed = False

    def prepare(self) -> None:
        """A fresh, empty staging folder; staging folders of dead runs into the same ``out`` are removed."""
        for old in self.out.parent.glob(f".{self.out.name}.staging-*"):
            shutil.rmtree(old, ignore_errors=True)  # we hold the lock: nobody else writes them
        self.path.mkdir(parents=True)

    def discard(self) -> None:
        shutil.rmtree(self.path, ignore_errors=True)

    def commit(self, status: str) -> None:
        """Write the manifest (``status``: completed, failed, interrupted) and move the run's files into place."""
        entries = file_entries(self.path)
        manifest = {"format": MANIFEST_FORMAT, "status": status, "files": entries}
        output.write_json(self.path / MANIFEST_PATH, manifest)
        out = self.out
        if not out.exists() and not out.is_symlink():
            os.rename(self.path, out)
            self.committed = True
            return
        old_manifest = out / MANIFEST_PATH
        held_a_run = old_manifest.is_file() or (out / "summary.json").is_file()  # else: a folder of the user's
        with contextlib.suppress(FileNotFoundError):
            old_manifest.unlink()  # from here on the folder reads as incomplete until the new manifest is in
        for name in _previous_files(out) if held_a_run else ():
            with contextlib.suppress(FileNotFoundError, IsADirectoryError):
                (out / name).unlink()
        for name in DERIVED if held_a_run else ():  # the previous run's report and export
            path = out / name
            if path.is_dir() and not path.is_symlink():
                shutil.rmtree(path, ignore_errors=True)
            elif path.exists() or path.is_symlink():
                path.unlink()
        for entry in entries:
            target = out / entry["name"]
            target.parent.mkdir(parents=True, exist_ok=True)
            os.replace(self.path / entry["name"], target)
        old_manifest.parent.mkdir(parents=True, exist_ok=True)
        os.replace(self.path / MANIFEST_PATH, old_manifest)
        self.committed = True
        self.discard()


def check_out(out: Path) -> None:
    """Refuse an ``out`` that exists but is not a folder (before anything runs)."""
    if out.exists() and not out.is_dir():
        raise RunFolderError(f"{out}: expected a folder for the run's outputs, found a file")


@contextlib.contextmanager
def writing(out: Path | str) -> Iterator[Staging]:
    """Lock ``out``, give the run a fresh staging folder, and discard it if the block fails before committing.

    An ``OSError`` in the block (a full disk, a file-size limit, no permission) becomes one
    :class:`RunFolderError` naming the file and the OS's reason; ``out`` is left as it was.
    """
    out = Path(out).absolute()  # "." has no name to put a lock or a staging folder beside
    check_out(out)
    with locked(out):
        staging = Staging(out)
        try:
            staging.prepare()
        except OSError as err:
            raise RunFolderError(f"{staging.path}: cannot create the staging folder: {os_reason(err)}") from None
        try:
            yield staging
        except OSError as err:
            staging.discard()
            raise RunFolderError(_write_failure(err, staging, out)) from None
        except BaseException:
            staging.discard()
            raise
        finally:
            if not staging.committed:
                staging.discard()


def _write_failure(err: OSError, staging: Staging, out: Path) -> str:
    name = err.filename
    where = str(name).replace(str(staging.path), str(out)) if name else str(out)
    kind = "disk full" if err.errno == errno.ENOSPC else "file too large" if err.errno == errno.EFBIG else "OS error"
    return f"{where}: cannot write the run's outputs ({kind}: {os_reason(err)}); {out} was left as it was"
