"""The external side of bench_live.py, run by Debian's /usr/bin/python3 (rospy): publishes
/tf for H humans (head and right hand joints) and N objects at 30 Hz, moves each human into
and out of its zone once a second at staggered times (live_scene.py), and listens to
/area_manager/factList.

    /usr/bin/python3 benchmarks/live_client.py HUMANS OBJECTS SECONDS [CYCLE]

(CYCLE: seconds of each human's in-and-out cycle, 1 by default.)

Prints one JSON object: ``toggles`` [[human, inside, publish wall ns]] and ``seen``
[[human, inside, receive wall ns]] (a change of the human's IsInArea zone_<human> in a
FactList).
"""

from __future__ import annotations

import importlib.util
import json
import sys
import time
from pathlib import Path

import rospy
from geometry_msgs.msg import TransformStamped
from tf2_msgs.msg import TFMessage

from live_scene import human_pose, joint_offsets, object_pose

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location(
    "toaster_ros1_messages", ROOT / "src" / "toaster" / "ros1" / "messages.py"
)
messages = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(messages)


def transform(child: str, x: float, y: float, z: float, stamp: rospy.Time) -> TransformStamped:
    t = TransformStamped()
    t.header.stamp = stamp
    t.header.frame_id = "map"
    t.child_frame_id = child
    t.transform.translation.x, t.transform.translation.y, t.transform.translation.z = x, y, z
    t.transform.rotation.w = 1.0
    return t


def main() -> None:
    humans, objects, seconds = int(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3])
    cycle = float(sys.argv[4]) if len(sys.argv) > 4 else 1.0
    # rospy sends from a thread of its own: hand it the interpreter within 1 ms, as the node
    # does, so that the client's Python does not add its own 5 ms steps to the latency
    sys.setswitchinterval(0.001)
    registry = messages.load()
    fact_list = messages.message_class("toaster_msgs/FactList", registry)
    rospy.init_node("bench_live_client", anonymous=True, disable_signals=True)
    pub = rospy.Publisher("/tf", TFMessage, queue_size=10)
    seen: list[list] = []
    inside_now: set[str] = set()

    def on_facts(msg) -> None:
        now = time.time_ns()
        current = {
            f.subjectId
            for f in msg.factList
            if f.property == "IsInArea" and f.targetId == f"zone_{f.subjectId}"
        }
        for human in current ^ inside_now:
            seen.append([human, human in current, now])
        inside_now.clear()
        inside_now.update(current)

    rospy.Subscriber(
        "/area_manager/factList", fact_list, on_facts, queue_size=100, tcp_nodelay=True
    )
    while pub.get_num_connections() == 0:
        time.sleep(0.05)
    time.sleep(1.0)
    inside = [False] * humans
    toggles: list[list] = []
    start = time.monotonic()
    tick = 0
    while time.monotonic() - start < seconds:
        elapsed = time.monotonic() - start
        stamp = rospy.Time.now()
        wall = time.time_ns()
        transforms = []
        for i in range(humans):
            want, x, y = human_pose(i, humans, elapsed, cycle)
            if want != inside[i]:
                inside[i] = want
                toggles.append([f"h{i}", want, wall])
            transforms.append(transform(f"h{i}_base", x, y, 0.0, stamp))
            transforms += [
                transform(f"h{i}_{joint}", x + dx, y + dy, dz, stamp)
                for joint, (dx, dy, dz) in joint_offsets().items()
            ]
        transforms += [transform(f"o{j}", *object_pose(j), stamp) for j in range(objects)]
        pub.publish(TFMessage(transforms=transforms))
        tick += 1
        time.sleep(max(0.0, start + tick / 30 - time.monotonic()))
    time.sleep(1.0)
    print(json.dumps({"toggles": toggles, "seen": seen}), flush=True)
    rospy.signal_shutdown("done")


if __name__ == "__main__":
    main()
