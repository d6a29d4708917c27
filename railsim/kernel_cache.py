"""Where numba keeps railsim's compiled kernels: a cache folder named by the kernels' sources.

The line laws, the plant and the free-run and line-step loops are numba functions compiled on first use and
cached on disk (``@njit(cache=True)``). numba checks a cached function against the time stamp of *its own* source
file only: the compiled line step inlines the ATO law of ``controllers/line_kernels.py`` and the forces of
``railsim/physics/forces.py``, so after a change to one of those (an edit, a ``git pull``) the step would go on
running the old law, silently. railsim therefore gives numba a cache folder per version of the kernel sources:
``~/.cache/railsim/numba/<hash>`` (``$XDG_CACHE_HOME`` if set), the hash taken over every Python file
of ``controllers/`` and ``railsim/physics/`` and the engine's ``*_kernel.py``. A changed source means a new folder
and a fresh compile; an unchanged tree finds its kernels again. Set ``NUMBA_CACHE_DIR`` yourself to choose the
folder (railsim then leaves it alone, and keeping it in step with the sources is yours).

:func:`configure` runs when :mod:`railsim` is imported, before any kernel is compiled (every kernel module imports
railsim first, directly or through :mod:`controllers`).
"""

from __future__ import annotations

import hashlib
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def kernel_sources(root: Path = ROOT) -> list[Path]:
    """The files whose change must recompile a kernel, in a fixed order."""
    files = [*(root / "controllers").rglob("*.py"), *(root / "railsim" / "physics").rglob("*.py")]
    files += (root / "railsim" / "engine").glob("*_kernel.py")
    return sorted(files)


def sources_hash(root: Path = ROOT) -> str:
    """A short hash of the kernel sources' paths and contents."""
    h = hashlib.sha256()
    for path in kernel_sources(root):
        h.update(path.relative_to(root).as_posix().encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def cache_dir(root: Path = ROOT) -> Path:
    """The folder for this version of the kernels (module docstring): under ``$XDG_CACHE_HOME`` (default
    ``~/.cache``), not under ``$RAILSIM_CACHE``, so runs that keep their worlds apart still share compiled code."""
    base = os.environ.get("XDG_CACHE_HOME")
    return (Path(base) if base else Path.home() / ".cache") / "railsim" / "numba" / sources_hash(root)


def configure() -> None:
    """Point numba at :func:`cache_dir` unless ``NUMBA_CACHE_DIR`` is set (before numba is imported, through
    the environment, which child processes inherit; after, through numba's config as well)."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return
    try:
        folder = str(cache_dir())
    except OSError:  # sources unreadable: leave numba's default (beside the sources)
        return
    os.environ["NUMBA_CACHE_DIR"] = folder
    config = sys.modules.get("numba.core.config")
    if config is not None:
        config.CACHE_DIR = folder  # type: ignore[attr-defined]
