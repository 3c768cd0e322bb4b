"""Subscriptions on ROS: ``/database_manager/watch`` opens a topic that publishes each event
matching a pattern as it is committed (``toaster.queries.watch`` in a thread of its own, with
a database connection of its own)."""

from __future__ import annotations

import threading
from typing import Any

from toaster.model import EventRow, Fact
from toaster.ros1.messages import Registry
from toaster.world.rosmsg import fact_fields

TOPIC_PREFIX = "/database_manager/watch/"


def event_fields(row: EventRow) -> dict[str, Any]:
    """toaster_msgs/BeliefEvent fields of an event row."""
    fact = Fact(
        row.subject_id,
        row.property,
        row.target_id,
        value_text=row.value_text or "",
        value_num=row.value_num,
        confidence=row.confidence or 0.0,
        observability=row.observability or 0.0,
        property_type=row.property_type,
        sub_property=row.sub_property,
        subject_owner_id=row.subject_owner_id,
        target_owner_id=row.target_owner_id,
    )
    return {
        "agentId": row.agent_id,
        "kind": row.kind,
        "previousValue": row.previous_text or "",
        "fact": fact_fields(fact, row.stamp_ns),
    }


class Watchers:
    """The open subscriptions of a bridge."""

    def __init__(self, rospy: Any, registry: Registry, url: str) -> None:
        self.rospy, self.registry, self.url = rospy, registry, url
        self.stop = threading.Event()
        self.threads: list[threading.Thread] = []
        self.publishers: list[Any] = []

    def open(self, agent: str, subject: str, prop: str, target: str) -> str:
        """Start publishing the events that match; return the topic."""
        from toaster.app.session import connect
        from toaster.queries import watch
        from toaster.ros1.messages import to_msg

        topic = f"{TOPIC_PREFIX}{len(self.publishers)}"
        cls = self.registry.msg("BeliefEvent")
        pub = self.rospy.Publisher(topic, cls, queue_size=1000, latch=False)
        self.publishers.append(pub)
        db = connect(self.url)
        stream = watch(
            db,
            agent=agent or None,
            subject=subject or None,
            property=prop or None,
            target=target or None,
            stop=self.stop,
        )

        def run() -> None:
            try:
                for row in stream:
                    pub.publish(to_msg(cls, event_fields(row), self.registry))
            finally:
                db.close()

        thread = threading.Thread(target=run, name=f"watch {topic}", daemon=True)
        thread.start()
        self.threads.append(thread)
        return topic

    def close(self) -> None:
        self.stop.set()
        for thread in self.threads:
            thread.join(2)
        for pub in self.publishers:
            pub.unregister()
