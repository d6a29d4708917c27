"""The golden harness's BLAS variants (``tests/golden.py``): a recorded outcome is accepted beside golden.json's,
recording one twice or recording golden.json's own does nothing, and the file keeps each machine's words."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tests import golden


@pytest.fixture
def files(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    (tmp_path / "golden.json").write_text(json.dumps({"case": {"trips.csv": "aa", "exit_code": "0"}}))
    monkeypatch.setattr(golden, "GOLDEN_FILE", tmp_path / "golden.json")
    monkeypatch.setattr(golden, "BLAS_VARIANTS_FILE", tmp_path / "variants.json")
    return tmp_path / "variants.json"


def test_a_recorded_variant_is_accepted_after_golden(files: Path) -> None:
    other = {"trips.csv": "bb", "exit_code": "0"}
    assert golden.accepted("case") == [{"trips.csv": "aa", "exit_code": "0"}]
    assert golden.record_variant("case", other, "a 4-core machine")
    assert golden.accepted("case") == [{"trips.csv": "aa", "exit_code": "0"}, other]
    assert json.loads(files.read_text())["case"][0]["machine"] == "a 4-core machine"


def test_golden_or_a_known_variant_is_not_recorded_again(files: Path) -> None:
    assert not golden.record_variant("case", {"trips.csv": "aa", "exit_code": "0"}, "here")
    assert not files.exists()
    assert golden.record_variant("case", {"trips.csv": "cc", "exit_code": "0"}, "there")
    assert not golden.record_variant("case", {"trips.csv": "cc", "exit_code": "0"}, "there again")
    assert len(golden.blas_variants()["case"]) == 1
