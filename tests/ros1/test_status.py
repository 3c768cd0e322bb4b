"""The live status of ``toaster serve --ros1``: the periodic line (node log and the latched
``/toaster/status`` topic), the ``/toaster/get_status`` service, and the counts printed on
exit. The window part's format is parsed by benchmarks: keep it."""

from __future__ import annotations

import re
import time

import pytest

from tests.processes import TIMEOUT, NodeProcess
from tests.ros1.conftest import RosClient

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)

WINDOW = re.compile(
    r"window (\d+) s: (\d+) ticks, p50 ([\d.]+) ms, p99 ([\d.]+) ms, "
    r"max ([\d.]+) ms, (\d+) overruns"
)
STATUS = re.compile(
    r"status: up (\d+) s, (\d+) ticks, (\d+) overruns, drops (.+), "
    r"(\d+) warnings"
)


@pytest.fixture(scope="module")
def node_args() -> list[str]:
    return ["--status-every", "1"]


def wait_log(node: NodeProcess, pattern: re.Pattern[str], count: int = 1) -> list[str]:
    deadline = time.monotonic() + TIMEOUT
    while True:
        found = [m.group(0) for m in pattern.finditer(node.stderr())]
        if len(found) >= count:
            return found
        if time.monotonic() > deadline or not node.alive():
            pytest.fail(
                f"no {count} lines matching {pattern.pattern} in the node's log: "
                f"{node.stderr()[-2000:]}"
            )
        time.sleep(0.1)


def test_status_line_topic_and_service_report_ticks_windows_and_drops(
    node: NodeProcess, client: RosClient
) -> None:
    client.publish(
        "/toaster_simu/objectList",
        "ObjectListStamped",
        {
            "header": {"stamp": "now", "frame_id": "map"},
            "objectList": [
                {
                    "meEntity": {
                        "id": "x" * 300,
                        "pose": {"position": {"x": 1}, "orientation": {"w": 1}},
                    }
                }
            ],
        },
    )
    lines = wait_log(node, re.compile(r"status: .*"), 2)
    windows = [WINDOW.search(line) for line in lines]
    assert all(windows), lines
    for found in windows:
        assert found is not None
        ticks, p50, p99, most = int(found[2]), float(found[3]), float(found[4]), float(found[5])
        assert ticks >= 0 and p50 <= p99 <= most
    assert all(STATUS.search(line) for line in lines), lines
    client.subscribe("/toaster/status", "std_msgs/String")
    published = client.latest("/toaster/status")["msg"]["data"]
    assert STATUS.search(published) and WINDOW.search(published), published

    def service() -> str:
        answer = client.call("/toaster/get_status", "std_srvs/Trigger")
        assert answer["success"]
        return str(answer["message"])

    deadline = time.monotonic() + TIMEOUT
    while "/toaster_simu/objectList id 1" not in (text := service()):
        assert time.monotonic() < deadline, text
        time.sleep(0.1)
    found = STATUS.search(text)
    assert found is not None and int(found[2]) > 0, text
    assert found[4].startswith("1 (/toaster_simu/objectList id 1)"), text


def test_counts_are_printed_on_exit(node: NodeProcess, client: RosClient) -> None:
    client.call("/toaster/get_status", "std_srvs/Trigger")
    out = node.close()
    last = next(line for line in out.splitlines() if "stopped after" in line)
    assert re.search(r"\d+ warnings; dropped 1 \(/toaster_simu/objectList id 1\)", last), last
    assert "Traceback" not in out
