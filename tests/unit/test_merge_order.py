"""The merge order's wait limit (railsim.engine.extensions.merge_order): the coupling timeout, ending 30 s before the
stall timeout would, so a train held back at a merge never reads as a stall; and when the extension applies."""

from __future__ import annotations

from types import SimpleNamespace

from railsim.engine.extensions.merge_order import MergeOrder, wait_limit_s


def test_the_wait_limit_is_the_coupling_timeout_at_most_half_the_stall_timeout() -> None:
    assert wait_limit_s(60.0, 300.0) == 60.0
    assert wait_limit_s(300.0, 300.0) == 270.0
    assert wait_limit_s(300.0, 1000.0) == 300.0


def test_it_applies_only_to_formations_that_couple_after_a_switch_or_at_a_station() -> None:
    def scenario(*kinds: str | None) -> object:
        couple = [None if k is None else SimpleNamespace(kind=k) for k in kinds]
        return SimpleNamespace(formations=[SimpleNamespace(couple=c) for c in couple])

    assert MergeOrder.applies(scenario("on_departure", "after_switch"))  # type: ignore[arg-type]
    assert MergeOrder.applies(scenario("on_departure", "at_station", None))  # type: ignore[arg-type]
    assert not MergeOrder.applies(scenario("on_departure", "at_s", None))  # type: ignore[arg-type]
    assert not MergeOrder.applies(scenario())  # type: ignore[arg-type]
