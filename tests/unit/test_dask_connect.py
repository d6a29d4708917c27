"""``--dask`` at something that is not a Dask scheduler ends in one ConfigError (exit 2) within its bound (10 + 5 s as shipped).

Two local servers on 127.0.0.1 stand in for a wrong address: one accepts and never answers (a firewall, a stuck
service), one answers every connection with an HTTP response (a web server's port).
"""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Iterator

import pytest

pytest.importorskip("distributed")

from railsim.errors import ConfigError  # noqa: E402
from railsim.studies.sweep import parallel  # noqa: E402
from railsim.studies.sweep.parallel import _connect  # noqa: E402


def _serve(respond: bytes | None) -> Iterator[int]:
    srv = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    srv.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    srv.bind(("127.0.0.1", 0))
    srv.listen(8)
    stop = threading.Event()
    held: list[socket.socket] = []

    def loop() -> None:
        srv.settimeout(0.2)
        while not stop.is_set():
            try:
                conn, _ = srv.accept()
            except OSError:
                continue
            held.append(conn)
            if respond is not None:
                try:
                    conn.settimeout(1.0)
                    conn.recv(65536)
                except OSError:
                    pass
                try:
                    conn.sendall(respond)
                except OSError:
                    pass

    th = threading.Thread(target=loop, daemon=True)
    th.start()
    try:
        yield srv.getsockname()[1]
    finally:
        stop.set()
        th.join(2)
        for c in held:
            c.close()
        srv.close()


@pytest.fixture
def silent_port() -> Iterator[int]:
    yield from _serve(None)


@pytest.fixture
def http_port() -> Iterator[int]:
    body = b"<html>not dask</html>"
    yield from _serve(b"HTTP/1.1 200 OK\r\nContent-Length: %d\r\n\r\n%s" % (len(body), body) * 50)


def test_the_shipped_bound_is_within_30_s() -> None:
    assert parallel.DASK_CONNECT_TIMEOUT_S + parallel.DASK_HANDSHAKE_GRACE_S <= 30.0


@pytest.mark.parametrize("server", ["silent_port", "http_port"])
def test_dask_at_a_port_that_is_no_scheduler_is_refused_within_its_bound(
    server: str, request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The same refusal with the bound shortened to 1 + 1 s (the shipped 10 + 5 s would keep a test worker idle
    for 15 s): the answer must come within the bound, whatever the port does."""
    monkeypatch.setattr(parallel, "DASK_CONNECT_TIMEOUT_S", 1.0)
    monkeypatch.setattr(parallel, "DASK_HANDSHAKE_GRACE_S", 1.0)
    port = request.getfixturevalue(server)
    t0 = time.perf_counter()
    with pytest.raises(ConfigError) as err:
        _connect(f"tcp://127.0.0.1:{port}")
    elapsed = time.perf_counter() - t0
    assert elapsed < 2.0 + 3.0, elapsed  # the bound, and time to import distributed in a cold worker
    assert err.value.field == "--dask" and f"127.0.0.1:{port}" in str(err.value)
    assert "\n" not in str(err.value)
