"""The engine's shape: tables that must agree, and the loop free of paper-specific branches."""

from __future__ import annotations

import ast
from pathlib import Path

from railsim.engine.timed import EVENT_HANDLERS
from railsim.scenario.events import EVENT_KINDS

ROOT = Path(__file__).resolve().parents[2]


def test_every_scenario_event_kind_has_an_engine_handler_and_back() -> None:
    keys = {kind.handler_key for kind in EVENT_KINDS.values()}
    assert keys == set(EVENT_HANDLERS), (keys, set(EVENT_HANDLERS))


def test_loop_module_names_no_paper_family() -> None:
    """Paper-specific behaviour lives in extensions: the loop's code names no paper module or controller type."""
    tree = ast.parse((ROOT / "railsim/engine/loop.py").read_text(encoding="utf-8"))
    names = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)} | {
        n.attr for n in ast.walk(tree) if isinstance(n, ast.Attribute)
    }
    strings = {n.value for n in ast.walk(tree) if isinstance(n, ast.Constant) and isinstance(n.value, str)}
    for word in ("monorail", "multipoint", "junction", "cooperative", "paper"):
        assert not any(word in x.lower() for x in names), word
        assert not any(word in s.lower() for s in strings if len(s) < 40), word


def test_module_sizes_stay_readable() -> None:
    """No railsim module over ~600 lines; the loop under 400."""
    sizes = {
        p.relative_to(ROOT).as_posix(): len(p.read_text(encoding="utf-8").splitlines())
        for p in (ROOT / "railsim").rglob("*.py")
    }
    assert sizes["railsim/engine/loop.py"] < 400
    too_long = {k: v for k, v in sizes.items() if v > 650}
    assert not too_long, too_long
