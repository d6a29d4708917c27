"""The bootstrap's choice of interpreter (``railsim/interpreter.py``): the fastest build of the default
``python3``'s version, only when it is clearly faster, never another version, never one that cannot make a venv.

The probes (each a child process) are replaced by their results: the rule is what is tested here; the probe itself
runs in every ``make`` that creates ``.venv`` (CI's included)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from railsim import interpreter

REAL = {
    "python3": "/opt/pyenv/3.11.7/bin/python3.11",
    "/usr/bin/python3.11": "/usr/bin/python3.11",
    "/usr/bin/python3": "/usr/bin/python3.11",  # the same build under another name: counted once
    "/usr/local/bin/python3.11": "/usr/local/bin/python3.11",
}


def _world(monkeypatch: pytest.MonkeyPatch, probes: dict[str, tuple[str, float] | None]) -> None:
    """Candidates by name -> (version, best seconds) or None (cannot make a venv / fails)."""
    monkeypatch.setattr(interpreter.shutil, "which", lambda name: "/opt/pyenv/shims/" + name)

    def fake_probe(python: str) -> tuple[str, str, float] | None:
        got = probes.get(python)
        return None if got is None else (REAL[python], got[0], got[1])

    monkeypatch.setattr(interpreter, "probe", fake_probe)
    monkeypatch.setattr(interpreter, "candidates", lambda version, probed: [p for p in probes if p != "python3"])


def test_a_clearly_faster_build_of_the_same_version_is_chosen(monkeypatch: pytest.MonkeyPatch) -> None:
    _world(monkeypatch, {"python3": ("3.11", 0.187), "/usr/bin/python3.11": ("3.11", 0.084)})
    assert interpreter.choose() == "/usr/bin/python3.11"


def test_a_build_within_the_noise_keeps_the_default(monkeypatch: pytest.MonkeyPatch) -> None:
    _world(monkeypatch, {"python3": ("3.11", 0.100), "/usr/bin/python3.11": ("3.11", 0.095)})
    assert interpreter.choose() == "python3"


def test_another_version_is_never_chosen(monkeypatch: pytest.MonkeyPatch) -> None:
    _world(monkeypatch, {"python3": ("3.11", 0.187), "/usr/local/bin/python3.11": ("3.12", 0.050)})
    assert interpreter.choose() == "python3"


def test_a_candidate_that_cannot_make_a_venv_is_dropped(monkeypatch: pytest.MonkeyPatch) -> None:
    _world(monkeypatch, {"python3": ("3.11", 0.187), "/usr/bin/python3.11": None, "/usr/bin/python3": None})
    assert interpreter.choose() == "python3"


def test_the_fastest_of_several_wins_and_aliases_count_once(monkeypatch: pytest.MonkeyPatch) -> None:
    _world(
        monkeypatch,
        {
            "python3": ("3.11", 0.187),
            "/usr/bin/python3": ("3.11", 0.090),
            "/usr/bin/python3.11": ("3.11", 0.080),  # the same executable as /usr/bin/python3: its first timing holds
            "/usr/local/bin/python3.11": ("3.11", 0.085),
        },
    )
    assert interpreter.choose() == "/usr/local/bin/python3.11"


def test_a_default_that_cannot_be_probed_is_used_as_it_is(monkeypatch: pytest.MonkeyPatch) -> None:
    _world(monkeypatch, {"python3": None, "/usr/bin/python3.11": ("3.11", 0.05)})
    assert interpreter.choose() == "python3"


def test_candidates_skip_what_was_probed_and_count_each_file_once(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Real files: the default's own command (a pyenv shim) is not probed again, and two names of one executable
    give one candidate."""
    bins = {name: tmp_path / name for name in ("shims", "usr_bin", "usr_local_bin")}
    for folder in bins.values():
        folder.mkdir()
    shim = bins["shims"] / "python3.11"
    shim.write_text("#!/bin/sh\n")
    debian = bins["usr_bin"] / "python3.11"
    debian.write_text("")
    (bins["usr_bin"] / "python3").symlink_to(debian)  # the same build under another name
    for f in (shim, debian):
        f.chmod(0o755)
    monkeypatch.setattr(interpreter, "FOLDERS", (str(bins["usr_bin"]), str(bins["usr_local_bin"])))
    monkeypatch.setattr(interpreter.shutil, "which", lambda name: str(shim) if name == "python3.11" else None)
    assert interpreter.candidates("3.11", set()) == [str(shim), str(debian)]
    assert interpreter.candidates("3.11", {os.path.realpath(shim)}) == [str(debian)]  # the default's command
