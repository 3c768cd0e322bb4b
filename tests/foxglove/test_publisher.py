"""The Foxglove server's publisher thread (toaster.foxglove.worker) in-process: the node's
thread sends /toaster/facts and hands the rest over; the publisher draws the scene, reads
beliefs and events on its own connection, keeps events in order, and survives its errors."""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

import toaster
from toaster.foxglove.worker import Publisher

pytest.importorskip("foxglove")
pytest.importorskip("websockets")
pytest.importorskip("google.protobuf")
pytest.importorskip("jsonschema")

from tests.foxglove.client import Client

#: the client connects outside a `with` (as in its own process)
pytestmark = pytest.mark.filterwarnings("ignore:connect\\(\\) must be used:DeprecationWarning")

ROOM = {"shape": "polygon", "points": [[-1, -1], [6, -1], [6, 2], [-1, 2]], "area_type": "room"}
IN, OUT = (1.0, 0.0, 0.0), (20.0, 0.0, 0.0)
SECOND = 1_000_000_000


class Served:
    """A node with a room, its Foxglove server and an in-process client on every channel."""

    def __init__(self, tmp_path: Path) -> None:
        from toaster.foxglove.server import start_server
        from toaster.node.live_node import LiveNode

        self.db = toaster.connect(f"sqlite:///{tmp_path / 'fox.db'}")
        self.db.store().put_area("kitchen", ROOM)
        self.node = LiveNode(self.db, holders="humans")
        self.server = start_server(self.node, port=0, services=False)
        self.client = Client(f"ws://127.0.0.1:{self.server.port}")
        self.t = 0
        channels = self.server.channels
        self.client.wait_for(lambda: channels.views_wanted() and channels.wanted(*TOPICS), 30)

    def tick(self, at: tuple[float, float, float]) -> None:
        self.t += SECOND // 10
        self.node.api.push("bob", at, kind="human", t_ns=self.t)
        self.node.api.push("cup", (3.0, 0.0, 0.8), kind="object", t_ns=self.t)
        self.node.tick(self.t)
        self.client.pump(0.01)

    def settle(self) -> None:
        """Every job handed over so far ran, and the client received what it sent."""
        assert self.server.output.publisher.flush(30)
        self.client.pump(1.0)

    def close(self) -> None:
        self.server.shutdown()
        self.client.ws.close()
        self.db.close()


TOPICS = ("/toaster/facts", "/toaster/events", "/toaster/beliefs", "/toaster/health")


@pytest.fixture
def served(tmp_path: Path) -> Iterator[Served]:
    s = Served(tmp_path)
    try:
        yield s
    finally:
        s.close()


def test_the_node_thread_sends_facts_and_never_draws_the_scene(
    served: Served, monkeypatch: pytest.MonkeyPatch
) -> None:
    import toaster.outputs.foxglove as fox

    drawn_on: list[str] = []
    scene_update = fox.scene_update

    def spy(*args: Any, **kwargs: Any) -> Any:
        drawn_on.append(threading.current_thread().name)
        return scene_update(*args, **kwargs)

    monkeypatch.setattr(fox, "scene_update", spy)
    for k in range(12):
        served.tick(IN if k % 2 else OUT)
    served.client.wait_for(lambda: served.client.messages.get("/toaster/scene"), 60)
    served.client.wait_for(lambda: served.client.messages.get("/toaster/facts"), 60)
    assert drawn_on and set(drawn_on) == {"toaster-foxglove"}, drawn_on


def test_events_go_out_in_order_and_none_is_lost(served: Served) -> None:
    from toaster import queries as q
    from toaster.outputs.recording import event_line

    for k in range(30):
        served.tick(IN if k % 2 else OUT)
        if k % 5 == 4:  # let reads happen between ticks (at most 5 Hz)
            time.sleep(0.25)
    time.sleep(1.1)  # the next tick reads again whatever changed
    served.tick(OUT)
    served.settle()
    got = [m["line"] for m in served.client.messages.get("/toaster/events", [])]
    stored = [event_line(e) for e in q.events(served.db)]
    assert len(got) >= 10, got
    assert got == stored[-len(got) :]
    stamps = [m["timestamp"] for m in served.client.messages["/toaster/events"]]
    assert stamps == sorted(stamps, key=lambda s: (s["sec"], s["nsec"]))


def test_a_publisher_error_is_logged_once_and_the_node_goes_on(
    served: Served, monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    from toaster.outputs import markers

    area_markers = markers.area_markers
    failures = [3]

    def broken(*args: Any, **kwargs: Any) -> Any:
        if failures[0] > 0:
            failures[0] -= 1
            msg = "drawing failed"
            raise RuntimeError(msg)
        return area_markers(*args, **kwargs)

    monkeypatch.setattr(markers, "area_markers", broken)
    publisher = served.server.output.publisher
    with caplog.at_level(logging.WARNING):
        k = 0
        while failures[0] > 0 or not served.client.messages.get("/toaster/areas"):
            served.tick(IN if k % 2 else OUT)
            assert publisher.flush(30)
            k += 1
            assert k < 600, "the areas never went out again"
    assert publisher.thread.is_alive()
    failed = [r for r in caplog.records if "FoxgloveOutput (views) failed" in r.getMessage()]
    assert len(failed) == 1, [r.getMessage() for r in caplog.records]
    assert any("works again after" in r.getMessage() for r in caplog.records)
    assert served.client.messages.get("/toaster/facts")


def test_latest_wins_per_kind_and_counts_what_it_replaced() -> None:
    ran: list[tuple[str, Any]] = []
    started, release = threading.Event(), threading.Event()

    def run(kind: str, job: Any) -> None:
        if job == "block":
            started.set()
            release.wait(30)
        ran.append((kind, job))

    publisher = Publisher(run, lambda kind, exc: None, lambda kind: None)
    publisher.submit("views", "block")
    assert started.wait(30)  # the thread runs it: what follows waits
    for n in range(5):
        publisher.submit("health", f"h{n}")
        publisher.submit("read", (n, n == 1), lambda old, new: (new[0], old[1] or new[1]))
    publisher.submit("views", "v")
    release.set()
    assert publisher.close()
    assert ran == [("views", "block"), ("views", "v"), ("read", (4, True)), ("health", "h4")]
    assert publisher.dropped == 8


def test_a_failing_job_does_not_end_the_thread() -> None:
    failed: list[str] = []

    def run(kind: str, job: Any) -> None:
        if job == "bad":
            msg = "bad job"
            raise RuntimeError(msg)

    publisher = Publisher(run, lambda kind, exc: failed.append(str(exc)), lambda kind: None)
    publisher.submit("health", "bad")
    assert publisher.flush(30)
    publisher.submit("health", "good")
    assert publisher.flush(30)
    assert publisher.thread.is_alive() and failed == ["bad job"]
    assert publisher.close()
