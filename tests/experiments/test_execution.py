"""A --scheduler address whose peer is no Dask scheduler (silent, an HTTP server, garbage) is one
line naming the address within the handshake's timeout, never a hang or "out of memory"."""

from __future__ import annotations

import contextlib
import http.server
import os
import socket
import threading
from collections.abc import Iterator

import pytest

pytest.importorskip("distributed", reason="needs the [distributed] extra")

from rmac_mj.cli import main  # noqa: E402
from rmac_mj.errors import EXIT_BAD_INPUT  # noqa: E402
from rmac_mj.experiments import execution  # noqa: E402

#: The handshake's timeout in these tests (the command's is DASK_CONNECT_SECONDS).
TIMEOUT = 0.5


@contextlib.contextmanager
def _listener(answer: bytes | None) -> Iterator[str]:
    """A TCP listener that accepts and then says ``answer`` (None: nothing; empty: hangs up at
    once), keeping each connection open until it is closed itself; yields its address."""
    server = socket.create_server(("127.0.0.1", 0))
    held = []

    def serve() -> None:
        while True:
            try:
                connection, _ = server.accept()
            except OSError:
                return
            if answer == b"":
                connection.close()
                continue
            held.append(connection)
            if answer is not None:
                connection.sendall(answer)

    threading.Thread(target=serve, daemon=True).start()
    try:
        yield f"tcp://127.0.0.1:{server.getsockname()[1]}"
    finally:
        server.close()
        for connection in held:
            connection.close()


@contextlib.contextmanager
def _http_server() -> Iterator[str]:
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), http.server.SimpleHTTPRequestHandler)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        yield f"tcp://127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()


@pytest.mark.parametrize(
    "peer, message",
    [
        (lambda: _listener(None), f"said nothing within {TIMEOUT:g} s"),
        (_http_server, f"said nothing within {TIMEOUT:g} s"),
        (lambda: _listener(os.urandom(64) * 16 + b"\xff" * 8), "not as a Dask scheduler"),
        (lambda: _listener(b"HTTP/1.0 400 Bad Request\r\n\r\n"), "not as a Dask scheduler"),
        (lambda: _listener(b"\x00" * 8), "not as a Dask scheduler"),
        (lambda: _listener(b""), "closed the connection without a word"),
    ],
)
def test_a_peer_that_is_no_scheduler_is_named_within_the_timeout(peer, message):
    with peer() as address:
        with pytest.raises(execution.BackendError) as refused:
            execution.connect_dask(address, timeout=TIMEOUT)
    assert address in str(refused.value) and message in str(refused.value)


def test_a_silent_scheduler_is_one_line_from_the_command(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(execution, "DASK_CONNECT_SECONDS", TIMEOUT)
    with _listener(None) as address:
        code = main(
            ["reproduce", "--algorithms", "s-ac", "--experiments", "1", "--trials", "1"]
            + ["--no-optimal", "--no-progress", "--scheduler", address, "--out", str(tmp_path)]
        )
    lines = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert code == EXIT_BAD_INPUT and len(lines) == 1, lines
    assert address in lines[0] and "out of memory" not in lines[0]
