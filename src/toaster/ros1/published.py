"""What the bridge publishes beside the fact lists, as the original's nodes did: area_manager's
area list (with its inside / upcoming / leaving entity lists, switched by publish_all_areas)
and database_manager's ``/database_manager/tables``.

Both run on the node's thread (the bridge's output). Service threads ask for the area lists
through :meth:`AreaOut.ask`, which the next tick answers: they never read the world.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from toaster.producers.area_lists import AreaLists, Lists
from toaster.ros1 import messages
from toaster.ros1.dbcalls import row_fields
from toaster.world.rosmsg import area_fields

if TYPE_CHECKING:
    from toaster.world.state import World

TABLES_TOPIC = "/database_manager/tables"
#: the tables are re-read when the node's producers changed a fact, else at least this often
#: (facts written by other processes: set_info, the CLI)
TABLES_EVERY_S = 1.0


class AreaOut:
    """``/area_manager/areaList`` (on until publish_all_areas switches it off) and the lists
    print_area asks for."""

    def __init__(self, node: Any, registry: Any, publisher: Any, numbers: Callable) -> None:
        self.node, self.registry, self.pub, self.numbers = node, registry, publisher, numbers
        self.lists = AreaLists(node.areas)
        self.on = True
        self._asked: list[tuple[threading.Event, dict[str, Lists]]] = []
        self._lock = threading.Lock()

    def toggle(self) -> bool:
        """publish_all_areas: switch the area list off or back on; the new state."""
        self.on = not self.on
        return self.on

    def ask(self, timeout_s: float = 2.0) -> dict[str, Lists] | None:
        """The areas' entity lists as of the next tick (any thread); None if no tick came."""
        done, found = threading.Event(), dict[str, Lists]()
        with self._lock:
            self._asked.append((done, found))
        return found if done.wait(timeout_s) else None

    def answer(self, t_ns: int, world: World) -> None:
        """Answer the waiting :meth:`ask` calls (every tick, on the node's thread)."""
        with self._lock:
            asked, self._asked = self._asked, []
        if asked:
            lists = self.lists.lists(world, t_ns)
            for done, found in asked:
                found.update(lists)
                done.set()

    def publish(self, t_ns: int, world: World) -> None:
        """The area list, every field of every area, while on and someone listens."""
        if not self.on or not self.pub.get_num_connections():
            return
        areas = self.node.areas.areas
        lists = self.lists.lists(world, t_ns)
        numbers = self.numbers(frozenset(areas))
        reg = self.registry
        fields = []
        for name, spec in sorted(areas.items()):
            found = lists.get(name, Lists([], [], []))
            area = area_fields(name, spec, numbers.get(name, 0), found.inside)
            area["upcomingEntities_"], area["leavingEntities_"] = found.upcoming, found.leaving
            fields.append(area)
        self.pub.publish(messages.to_msg(reg.msg("AreaList"), {"areaList": fields}, reg))


class TablesOut:
    """``/database_manager/tables``: one DatabaseTable per agent (its current facts), its
    ``changed`` true in the first message after the agent's facts changed, as the original."""

    def __init__(self, node: Any, registry: Any, publisher: Any) -> None:
        self.node, self.registry, self.pub = node, registry, publisher
        self._last: dict[str, list[dict[str, Any]]] = {}
        self._events = -1
        self._read_at = 0.0

    def publish(self) -> None:
        """Publish the tables (re-read when facts may have changed) while someone listens."""
        if self.node.db is None or not self.pub.get_num_connections():
            return
        events = self.node.runner.stats.events
        now = time.monotonic()
        changed: set[str] = set()
        if events != self._events or now - self._read_at >= TABLES_EVERY_S:
            from toaster import queries as q

            self._events, self._read_at = events, now
            db = self.node.read_db  # the node thread's own connection (the writer's is busy)
            tables: dict[str, list[dict[str, Any]]] = {a.id: [] for a in q.agents(db)}
            for row in q.current_facts(db, list(tables)):
                tables[row.agent_id].append(row_fields(row))
            changed = {a for a, facts in tables.items() if facts != self._last.get(a)}
            self._last = tables
        reg = self.registry
        msg = {
            "tables": [
                {"agentName": agent, "facts": facts, "changed": agent in changed}
                for agent, facts in self._last.items()
            ]
        }
        self.pub.publish(messages.to_msg(reg.msg("DatabaseTables"), msg, reg))
