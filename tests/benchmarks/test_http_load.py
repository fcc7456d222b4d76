"""The open-loop read client of the benchmarks (benchmarks/http_load.py) against a real socket server.

The server here is a small asyncio HTTP/1.1 responder written for the test, so that every framing the client
must read (a ``Content-Length``, chunks with a trailer, a body ended by closing) and every failure (a
keep-alive connection the server dropped, a request never answered) happens on purpose.  Nothing is timed
against a bound: a latency is checked only to include a delay the server is known to have taken.
"""

from __future__ import annotations

import asyncio
import threading
from contextlib import contextmanager

from benchmarks.http_load import latency_table, open_loop_get

SLOW_S = 0.2


async def _answer(reader: asyncio.StreamReader, writer: asyncio.StreamWriter, seen: list[str]) -> None:
    while True:
        try:
            head = await reader.readuntil(b"\r\n\r\n")
        except (asyncio.IncompleteReadError, ConnectionError):
            break
        path = head.split(b" ")[1].decode()
        seen.append(path + (" auth" if b"\r\nAuthorization: Bearer t\r\n" in head else ""))
        if path == "/len":
            writer.write(b"HTTP/1.1 200 OK\r\nContent-Length: 5\r\n\r\nhello")
        elif path == "/chunked":
            writer.write(b"HTTP/1.1 201 Created\r\nTransfer-Encoding: chunked\r\n\r\n"
                         b"3\r\nabc\r\n4;ext=1\r\ndefg\r\n0\r\nX-Trailer: 1\r\n\r\n")
        elif path == "/slow":
            await asyncio.sleep(SLOW_S)
            writer.write(b"HTTP/1.1 200 OK\r\nContent-Length: 2\r\n\r\nok")
        elif path == "/until-close":
            writer.write(b"HTTP/1.1 404 Not Found\r\n\r\nno length: ends with the connection")
            await writer.drain()
            break
        elif path == "/then-drop":  # says keep-alive, then drops the connection (a keep-alive timeout)
            writer.write(b"HTTP/1.1 200 OK\r\nContent-Length: 2\r\n\r\nok")
            await writer.drain()
            break
        elif path == "/no-content":  # no body and no length, by definition
            writer.write(b"HTTP/1.1 204 No Content\r\n\r\n")
        elif path == "/garbled":
            writer.write(b"HTTP/1.1\r\n\r\n")
            await writer.drain()
            break
        elif path == "/hang":
            await asyncio.sleep(3600)
        await writer.drain()
    writer.close()


@contextmanager
def _server():
    """``(base URL, connections accepted, paths requested)`` of a server running in a thread of its own."""
    loop = asyncio.new_event_loop()
    accepted: list[int] = []
    seen: list[str] = []

    async def on_connect(reader, writer):
        accepted.append(1)
        await _answer(reader, writer, seen)

    server = loop.run_until_complete(asyncio.start_server(on_connect, "127.0.0.1", 0))
    port = server.sockets[0].getsockname()[1]
    thread = threading.Thread(target=loop.run_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{port}", accepted, seen
    finally:
        loop.call_soon_threadsafe(loop.stop)
        thread.join(10)
        assert not thread.is_alive()


def test_every_framing_is_read_and_the_status_kept():
    paths = ["/len", "/chunked", "/until-close", "/slow", "/no-content", "/garbled"]
    with _server() as (base, _, seen):
        reads = open_loop_get(base, {"Authorization": "Bearer t"}, paths, rate=30, seconds=0.4, timeout_s=5)
    assert sorted((r.path, r.status) for r in reads) == sorted(  # a malformed answer counts as none
        [("/len", 200), ("/chunked", 201), ("/until-close", 404), ("/slow", 200), ("/no-content", 204),
         ("/garbled", -1)] * 2)
    assert sorted(seen) == sorted(f"{p} auth" for p in paths * 2)  # the headers go with every request
    slow = [r for r in reads if r.path == "/slow"]
    assert all(r.ms >= SLOW_S * 1000 for r in slow)  # from its scheduled time to the answer's last byte
    assert all(0 <= r.late_ms <= r.ms for r in reads)
    table = latency_table(reads, paths)
    assert "| /chunked | 2 |" in table and "| **all** | 12 |" in table and "after its scheduled time" in table


def test_idle_connections_are_reused_and_a_dropped_one_replaced():
    with _server() as (base, accepted, _):
        reads = open_loop_get(base, {}, ["/len"], rate=10, seconds=0.4)  # one at a time: one connection
        assert [r.status for r in reads] == [200] * 4 and len(accepted) == 1
        accepted.clear()
        reads = open_loop_get(base, {}, ["/then-drop", "/len"], rate=10, seconds=0.4)
        # each /len finds the connection /then-drop left idle dropped by the server and goes again on a new one,
        # which the next /then-drop reuses: connections A (drop), B (/len, then drop), C (/len)
        assert [r.status for r in reads] == [200] * 4 and len(accepted) == 3


def test_a_request_without_an_answer_is_counted_once_the_timeout_ends():
    with _server() as (base, _, _):
        reads = open_loop_get(base, {}, ["/hang", "/len"], rate=10, seconds=0.2, timeout_s=0.5)
    assert sorted((r.path, r.status) for r in reads) == [("/hang", -1), ("/len", 200)]
    hung = next(r for r in reads if r.path == "/hang")
    assert hung.ms >= 500
