"""The extension API (railsim.engine.extensions.base): named no-op hooks, called through the ExtensionSet in
installation order, only on the extensions that override them; and a context without untyped fields."""

from __future__ import annotations

import dataclasses
from typing import Any

import pytest

from railsim.engine.extensions import Extension, ExtensionContext, ExtensionSet
from railsim.engine.extensions.base import HOOKS
from railsim.engine.extensions.registry import EXTENSIONS


class _Recorder(Extension):
    """Records the hook calls it gets into a shared list."""

    def __init__(self, name: str, calls: list[tuple[str, str]]) -> None:  # no context needed here
        self.name, self.calls = name, calls


class _Plant(_Recorder):
    summary_key = "plant"

    def on_inserted(self, t: float, tr: Any, chainage_m: float) -> None:
        self.calls.append((self.name, "on_inserted"))

    def ato_extras(self, t: float, tr: Any) -> dict[str, Any]:
        return {"shared": self.name, self.name: 1}

    def summary(self) -> dict[str, Any]:
        return {"n": 1}


class _Driver(_Recorder):
    def drives(self, train_id: str) -> bool:
        return train_id == "T1"

    def manages_lock(self, train_id: str, switch_id: str) -> bool:
        return (train_id, switch_id) == ("T1", "sw1")

    def defers_lock(self, train_id: str, switch_id: str) -> bool:
        return (train_id, switch_id) == ("T2", "sw1")

    def t2t_receivers(self, train_id: str) -> list[str]:
        return [f"{self.name}-{train_id}"]

    def before_bookkeeping(self, t: float) -> None:
        self.calls.append((self.name, "before_bookkeeping"))


def test_hooks_run_in_installation_order_on_the_extensions_that_override_them() -> None:
    calls: list[tuple[str, str]] = []
    a, b, idle, c = _Plant("a", calls), _Driver("b", calls), _Recorder("idle", calls), _Plant("c", calls)
    ext = ExtensionSet()
    ext.install([a, b, idle, c])
    assert ext.overriding("on_inserted") == (a, c)
    assert ext.overriding("drives") == (b,)
    assert all(idle not in ext.overriding(h) for h in HOOKS)

    ext.on_inserted(0.0, None, 0.0)  # type: ignore[arg-type]
    ext.before_bookkeeping(1.0)
    ext.before_comms(1.0, [])
    assert calls == [("a", "on_inserted"), ("c", "on_inserted"), ("b", "before_bookkeeping")]
    assert ext.ato_extras(0.0, None) == {"shared": "c", "a": 1, "c": 1}  # type: ignore[arg-type]  # later wins
    assert ext.driver_of("T1") is b and ext.driver_of("T2") is None
    assert ext.manages_lock("T1", "sw1") and not ext.manages_lock("T1", "sw2")
    assert ext.defers_lock("T2", "sw1") and not ext.defers_lock("T1", "sw1")
    assert list(ext.t2t_receivers("T1")) == ["b-T1"]
    assert ext.summaries() == {"plant": {"n": 1}}  # one key: the later extension of the same key replaces it


def test_an_empty_set_answers_like_no_extension_and_installs_once() -> None:
    ext = ExtensionSet()
    assert ext.installed is None
    ext.install([])
    assert ext.installed == ()
    assert ext.ato_extras(0.0, None) == {}  # type: ignore[arg-type]
    assert ext.driver_of("T1") is None and not ext.manages_lock("T1", "sw1") and not ext.defers_lock("T1", "sw1")
    assert list(ext.t2t_receivers("T1")) == [] and ext.summaries() == {}
    with pytest.raises(RuntimeError, match="installed once"):
        ext.install([])


def test_every_hook_is_a_no_op_method_of_the_base() -> None:
    base = Extension.__new__(Extension)
    for hook in HOOKS:
        assert callable(getattr(Extension, hook))
    assert base.ato_extras(0.0, None) == {}  # type: ignore[arg-type]
    assert base.drives("T1") is False and base.manages_lock("T1", "sw1") is False
    assert base.defers_lock("T1", "sw1") is False
    assert list(base.t2t_receivers("T1")) == [] and base.summary() == {}
    assert Extension.applies(None) is False  # type: ignore[arg-type]


def test_the_shipped_extensions_are_subclasses_that_say_when_they_apply() -> None:
    for cls in EXTENSIONS:
        assert issubclass(cls, Extension)
        assert cls.applies is not Extension.applies, cls.__name__


def test_the_context_has_no_untyped_field() -> None:
    """Every field is a real class, a protocol or a precise callable: none is ``Any``."""
    fields = {f.name: str(f.type) for f in dataclasses.fields(ExtensionContext)}
    assert fields and not {name: t for name, t in fields.items() if "Any" in t}


def test_the_architecture_guide_example_is_an_extension_that_runs_its_hooks() -> None:
    """The sketch in docs/architecture.md ("A new paper extension") is valid code of this API."""
    import re
    from pathlib import Path
    from types import SimpleNamespace

    text = (Path(__file__).resolve().parents[2] / "docs" / "architecture.md").read_text(encoding="utf-8")
    block = re.search(r"```python\n(.*?class \w+\(Extension\).*?)```", text, re.S)
    assert block is not None
    ns: dict[str, Any] = {}
    exec(compile(block.group(1), "architecture.md", "exec"), ns)
    cls = next(v for v in ns.values() if isinstance(v, type) and issubclass(v, Extension) and v is not Extension)
    ext = cls(None)
    ext_set = ExtensionSet()
    ext_set.install([ext])
    for i in range(3):
        ext_set.on_inserted(float(i), SimpleNamespace(train_id=f"T{i}"), 0.0)  # type: ignore[arg-type]
    assert ext_set.ato_extras(0.0, SimpleNamespace(train_id="T2")) == {"trains_before": 2}  # type: ignore[arg-type]
    assert ext_set.summaries() == {cls.summary_key: {"inserted": 3}}
