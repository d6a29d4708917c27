"""numba's cache folder follows the kernel sources (railsim.kernel_cache): a change to a law in another module
than the compiled loop that inlines it must not leave the loop's stale compiled code in use."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from railsim import kernel_cache


def _tree(root: Path) -> None:
    for rel, text in {
        "controllers/line_kernels.py": "def ato(): return 1\n",
        "controllers/mcf_dmpc/kernels.py": "K = 1\n",
        "railsim/physics/forces.py": "G = 9.81\n",
        "railsim/engine/line_step_kernel.py": "from controllers.line_kernels import ato\n",
        "railsim/engine/loop.py": "X = 1\n",
    }.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(text)


def test_the_folder_changes_with_a_law_in_another_module_and_only_with_kernel_sources(tmp_path: Path) -> None:
    _tree(tmp_path)
    names = [p.relative_to(tmp_path).as_posix() for p in kernel_cache.kernel_sources(tmp_path)]
    assert names == [
        "controllers/line_kernels.py",
        "controllers/mcf_dmpc/kernels.py",
        "railsim/engine/line_step_kernel.py",
        "railsim/physics/forces.py",
    ]
    before = kernel_cache.sources_hash(tmp_path)
    assert kernel_cache.sources_hash(tmp_path) == before  # deterministic
    (tmp_path / "railsim/engine/loop.py").write_text("X = 2\n")  # not a kernel source
    assert kernel_cache.sources_hash(tmp_path) == before
    (tmp_path / "controllers/line_kernels.py").write_text("def ato(): return 2\n")  # the inlined law changes
    assert kernel_cache.sources_hash(tmp_path) != before


def test_configure_names_a_folder_under_the_user_cache_and_respects_the_users_choice(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.setenv("RAILSIM_CACHE", str(tmp_path / "worlds"))  # worlds apart: compiled code still shared
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    import numba.core.config

    monkeypatch.setattr(numba.core.config, "CACHE_DIR", numba.core.config.CACHE_DIR)  # restored afterwards
    kernel_cache.configure()
    folder = Path(os.environ["NUMBA_CACHE_DIR"])
    assert folder.parent == tmp_path / "railsim" / "numba" and folder.name == kernel_cache.sources_hash()
    assert numba.core.config.CACHE_DIR == str(folder)
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "mine"))
    kernel_cache.configure()
    assert os.environ["NUMBA_CACHE_DIR"] == str(tmp_path / "mine")
