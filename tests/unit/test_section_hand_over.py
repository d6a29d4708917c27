"""A unit that arrives inside a single-track section and turns back there keeps the section for its next trip.

Found on Jena's peak: tram ``5_lobeda-ost_ernst-abbe-platz.000`` arrived at Ernst-Abbe-Platz, a single-track bidi
terminus, and released the section; the queue granted it to a train waiting to enter it the other way, while the
unit reversed and ran to its departure platform inside the section without holding it. A train then entered
head-on: SUMO reported a frontal collision for 6 s. :meth:`TrackSections.hand_over` passes the granted
reservation to the unit's next trip at once, with no waiting train let in between."""

from __future__ import annotations

from railsim.engine.events.log import EventLog
from railsim.engine.events.tracks import TrackSections

SECTION = "track:-157032680"


def test_the_section_passes_to_the_next_trip_and_the_train_waiting_head_on_stays_out() -> None:
    events = EventLog()
    tracks = TrackSections(events, [SECTION])
    arriving = tracks.request(1133.5, ("5_lobeda-ost_ernst-abbe-platz.000",), SECTION, 0)
    waiting = tracks.request(1200.0, ("33_ernst-abbe-platz_jena-ost.002",), SECTION, 1)
    assert arriving.granted and not waiting.granted
    turned = tracks.hand_over(1255.0, arriving, "5_ernst-abbe-platz_lobeda-ost.002", 196)
    assert turned is not None and turned.granted
    assert tracks.holders(SECTION) == ("5_ernst-abbe-platz_lobeda-ost.002",)
    assert not waiting.granted  # the train waiting to enter head-on was not let in between
    tracks.release(1520.0, "5_ernst-abbe-platz_lobeda-ost.002", turned)
    assert waiting.granted  # once the unit has left the section
    kinds = [e.kind for e in events.entries(subject=SECTION)]
    assert kinds.count("section_handed_over") == 1


def test_no_hand_over_while_a_train_in_the_old_direction_is_still_in_the_section() -> None:
    tracks = TrackSections(EventLog(), [SECTION])
    arriving = tracks.request(0.0, ("a.000",), SECTION, 0)
    behind = tracks.request(10.0, ("b.000",), SECTION, 0)  # follows it into the section
    assert arriving.granted and behind.granted
    assert tracks.hand_over(60.0, arriving, "a.001", 5) is None  # the turned unit would meet b head-on
    assert set(tracks.holders(SECTION)) == {"a.000", "b.000"}
