"""A ROS 1 test client run by Debian's /usr/bin/python3 (rospy): JSON commands in on stdin,
one JSON answer per line out on stdout.

Commands: {"op": "call", "service", "type", "request"}; {"op": "publish", "key", "topic",
"type", "msg", "rate"} (rate 0: once, after a subscriber connected; a header stamp "now" is
filled at each send); {"op": "stop", "key"}; {"op": "subscribe", "topic", "type"};
{"op": "latest", "topic", "after", "timeout"} (the newest message received after the
``after``-th one); {"op": "quit"}.
"""

from __future__ import annotations

import importlib
import importlib.util
import json
import sys
import threading
import time
from pathlib import Path

import rospy

HERE = Path(__file__).resolve().parent
#: How long to wait for a connection or a message: generous, a loaded machine is slow.
CONNECT_S = 60.0
_spec = importlib.util.spec_from_file_location(
    "toaster_ros1_messages", HERE.parents[1] / "src" / "toaster" / "ros1" / "messages.py"
)
messages = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(messages)
REGISTRY = messages.load()


def msg_class(type_name: str):
    return messages.message_class(
        type_name if "/" in type_name else f"toaster_msgs/{type_name}", REGISTRY
    )


def stamped(data):
    """A copy of ``data`` with every "now" stamp replaced by the current time in ns."""
    if isinstance(data, dict):
        return {
            k: (rospy.Time.now().to_nsec() if k == "stamp" and v == "now" else stamped(v))
            for k, v in data.items()
        }
    if isinstance(data, list):
        return [stamped(v) for v in data]
    return data


class Client:
    def __init__(self) -> None:
        self.publishers: dict[str, rospy.Publisher] = {}
        self.loops: dict[str, tuple[threading.Event, threading.Thread]] = {}
        self.received: dict[str, list] = {}
        self.cond = threading.Condition()
        self.subs = []

    def publisher(self, topic: str, type_name: str):
        if topic not in self.publishers:
            latch = topic == "/tf_static"
            self.publishers[topic] = rospy.Publisher(
                topic, msg_class(type_name), queue_size=10, latch=latch
            )
        return self.publishers[topic]

    def call(self, cmd):
        srv = REGISTRY.srv(cmd["type"])
        rospy.wait_for_service(cmd["service"], timeout=10)
        proxy = rospy.ServiceProxy(cmd["service"], srv)
        request = messages.to_msg(srv._request_class, cmd.get("request", {}), REGISTRY)
        try:
            return {"ok": True, "response": messages.from_msg(proxy(request))}
        except rospy.ServiceException as exc:
            return {"ok": False, "error": str(exc)}

    def publish(self, cmd):
        key = cmd.get("key", cmd["topic"])
        self.stop({"key": key})
        pub = self.publisher(cmd["topic"], cmd["type"])
        cls = msg_class(cmd["type"])
        rate = float(cmd.get("rate", 0))
        if rate <= 0:
            deadline = time.monotonic() + CONNECT_S
            while pub.get_num_connections() == 0 and time.monotonic() < deadline:
                time.sleep(0.02)
            pub.publish(messages.to_msg(cls, stamped(cmd["msg"]), REGISTRY))
            return {"ok": True, "connections": pub.get_num_connections()}
        stop = threading.Event()

        def loop():
            while not stop.is_set():
                pub.publish(messages.to_msg(cls, stamped(cmd["msg"]), REGISTRY))
                stop.wait(1.0 / rate)

        thread = threading.Thread(target=loop, daemon=True)
        thread.start()
        self.loops[key] = (stop, thread)
        return {"ok": True}

    def stop(self, cmd):
        found = self.loops.pop(cmd["key"], None)
        if found:
            found[0].set()
            found[1].join()
        return {"ok": True}

    def subscribe(self, cmd):
        topic = cmd["topic"]
        if topic in self.received:
            return {"ok": True}
        self.received[topic] = []

        def got(msg):
            with self.cond:
                self.received[topic].append(messages.from_msg(msg))
                del self.received[topic][:-5]
                self.received[topic + "#"] = self.received.get(topic + "#", 0) + 1
                self.cond.notify_all()

        sub = rospy.Subscriber(topic, msg_class(cmd["type"]), got, queue_size=10)
        self.subs.append(sub)
        if cmd.get("connected"):  # wait for the publisher: what it sends next is received
            deadline = time.monotonic() + float(cmd["connected"])
            while sub.get_num_connections() == 0:
                if time.monotonic() > deadline:
                    return {"ok": False, "error": f"no publisher of {topic} connected"}
                time.sleep(0.02)
        return {"ok": True}

    def latest(self, cmd):
        topic, after = cmd["topic"], int(cmd.get("after", 0))
        deadline = time.monotonic() + float(cmd.get("timeout", CONNECT_S))
        with self.cond:
            while self.received.get(topic + "#", 0) <= after:
                left = deadline - time.monotonic()
                if left <= 0:
                    return {"ok": False, "error": f"no message on {topic}"}
                self.cond.wait(left)
            return {
                "ok": True,
                "msg": self.received[topic][-1],
                "count": self.received[topic + "#"],
            }


def main() -> None:
    rospy.init_node("toaster_test_client", anonymous=True, disable_signals=True)
    client = Client()
    print(json.dumps({"ok": True, "ready": True}), flush=True)
    for line in sys.stdin:
        cmd = json.loads(line)
        if cmd["op"] == "quit":
            break
        try:
            answer = getattr(client, cmd["op"])(cmd)
        except Exception as exc:  # report, keep serving
            answer = {"ok": False, "error": f"{type(exc).__name__}: {exc}"}
        print(json.dumps(answer), flush=True)
    for key in list(client.loops):
        client.stop({"key": key})
    rospy.signal_shutdown("done")


if __name__ == "__main__":
    main()
