"""When the compiled core is loaded (railsim.native.activate): only a build whose stamp matches the sources in
the tree and this interpreter; otherwise the interpreted modules, and an out-of-date build says so."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from railsim import native


def _stamped(tmp_path: Path, **changes: str) -> Path:
    build = tmp_path / "native"
    build.mkdir()
    (build / native.STAMP_FILE).write_text(json.dumps({**native.fingerprint(), **changes}), encoding="utf-8")
    return build


def test_without_a_build_the_interpreted_modules_load(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(native.ENV, raising=False)
    assert native._activate(tmp_path / "none") == ("interpreted (the compiled core is not built: make native)", None)


def test_asked_for_by_the_environment_the_interpreted_modules_load(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(native.ENV, "0")
    assert native._activate(_stamped(tmp_path)) == ("interpreted (RAILSIM_NATIVE=0)", None)


@pytest.mark.parametrize(("field", "what"), [("sources_sha256", "sources"), ("python", "interpreter")])
def test_a_build_for_other_sources_or_another_interpreter_is_not_loaded_and_says_so(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], field: str, what: str
) -> None:
    monkeypatch.delenv(native.ENV, raising=False)
    status, notice = native._activate(_stamped(tmp_path, **{field: "other"}))
    assert status == f"interpreted (the compiled core is out of date: other {what})"
    assert notice is not None and capsys.readouterr().err == ""  # nothing yet: no engine module imported
    assert notice.find_spec("json", None) is None and capsys.readouterr().err == ""
    assert notice.find_spec("railsim.engine.loop", None) is None  # it finds nothing: the sources load
    assert f"was built for other {what}; running interpreted" in capsys.readouterr().err
    notice.find_spec("railsim.engine.control", None)
    assert capsys.readouterr().err == ""  # once


def test_a_matching_stamp_without_its_extension_modules_is_not_loaded(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delenv(native.ENV, raising=False)
    assert native._activate(_stamped(tmp_path))[0].startswith(
        "interpreted (the compiled core's build folder is incomplete"
    )


def test_the_fingerprint_follows_every_compiled_source() -> None:
    assert all(native.source_of(m).is_file() for m in native.MODULES)
    assert len(set(native.MODULES)) == len(native.MODULES)
