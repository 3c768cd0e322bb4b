"""The temporal invariants every writer must keep, checked in SQL (``toaster db check``).

For every key of every holder (its own intervals and the self's intervals it follows, as the
``fact_history`` view shows them): no two intervals overlap, at most one is open, and each
boundary has its event in ``event_log`` (``appeared`` where an interval starts after none or
after a gap, ``changed`` where it follows one of another value, ``ended`` where one ends with
none after it; where one continues another of the same value, no event or an ``ended`` and an
``appeared``), and every such event has its boundary. Each check is one query; a violation
is one line.
"""

from __future__ import annotations

from sqlalchemy import Connection, text

#: Each interval of ``fact_history`` with its neighbours on the same key.
_ORDERED = """
SELECT key_id, agent_id, property, subject_id, target_id, value_text, valid_from_ns,
       valid_to_ns,
       LAG(valid_to_ns) OVER w AS prev_to, LAG(value_text) OVER w AS prev_value,
       LAG(valid_from_ns) OVER w AS prev_from,
       LEAD(valid_from_ns) OVER w AS next_from, LEAD(value_text) OVER w AS next_value,
       ROW_NUMBER() OVER w AS position
FROM fact_history
WINDOW w AS (PARTITION BY key_id ORDER BY valid_from_ns,
             CASE WHEN valid_to_ns IS NULL THEN 1 ELSE 0 END, valid_to_ns)
"""

_OVERLAPS = f"""
SELECT agent_id, subject_id, property, target_id, prev_from, prev_to, valid_from_ns
FROM ({_ORDERED}) o
WHERE position > 1 AND (prev_to IS NULL OR prev_to > valid_from_ns)
ORDER BY agent_id, key_id, valid_from_ns
"""

_OPEN_TWICE = """
SELECT agent_id, subject_id, property, target_id, COUNT(*) FROM fact_history
WHERE valid_to_ns IS NULL GROUP BY key_id, agent_id, subject_id, property, target_id
HAVING COUNT(*) > 1
"""

#: The events the intervals call for: (key, kind, stamp), once per boundary.
_EXPECTED = """
SELECT key_id, CASE WHEN prev_to = valid_from_ns THEN 'changed' ELSE 'appeared' END AS kind,
       valid_from_ns AS stamp_ns
FROM ordered o
WHERE NOT (prev_to IS NOT NULL AND prev_to = valid_from_ns AND prev_value = value_text)
UNION ALL
SELECT key_id, 'ended', valid_to_ns FROM ordered o
WHERE valid_to_ns IS NOT NULL AND (next_from IS NULL OR next_from <> valid_to_ns)
"""

#: Boundaries (``expected``) and events (``actual``) counted per (key, kind, stamp), each
#: computed once. Where one interval continues another of the same value (a merge) there is
#: either no event (a holder's own interval handed over to a followed one) or an ``ended``
#: and an ``appeared`` (a fact retracted and asserted again at one time): as many such pairs
#: as there are both events beyond the boundaries' own, at most one per merge, are left out
#: of ``actual``. (Leaving out every ended and appeared at a merge's stamp also hid the
#: events of an empty interval there: asserted, retracted and asserted again at one time.)
_COUNTED = f"""
WITH ordered AS MATERIALIZED ({_ORDERED}),
expected AS MATERIALIZED (
  SELECT key_id, kind, stamp_ns, COUNT(*) AS n FROM ({_EXPECTED}) b
  GROUP BY key_id, kind, stamp_ns),
logged AS MATERIALIZED (
  SELECT key_id, kind, stamp_ns, COUNT(*) AS n FROM event_log WHERE kind <> 'event'
  GROUP BY key_id, kind, stamp_ns),
merges AS (
  SELECT key_id, valid_from_ns AS stamp_ns, COUNT(*) AS n FROM ordered
  WHERE prev_to IS NOT NULL AND prev_to = valid_from_ns AND prev_value = value_text
  GROUP BY key_id, valid_from_ns),
extra AS (
  SELECT key_id, stamp_ns, SUM(CASE kind WHEN 'ended' THEN n ELSE 0 END) AS ended,
         SUM(CASE kind WHEN 'appeared' THEN n ELSE 0 END) AS appeared
  FROM (SELECT key_id, kind, stamp_ns, n FROM logged
        UNION ALL SELECT key_id, kind, stamp_ns, -n FROM expected) u
  GROUP BY key_id, stamp_ns),
pairs AS (
  SELECT m.key_id, m.stamp_ns,
         CASE WHEN x.ended < 0 OR x.appeared < 0 THEN 0
              WHEN x.ended <= x.appeared AND x.ended <= m.n THEN x.ended
              WHEN x.appeared <= m.n THEN x.appeared ELSE m.n END AS n
  FROM merges m JOIN extra x ON x.key_id = m.key_id AND x.stamp_ns = m.stamp_ns),
actual AS (
  SELECT e.key_id, e.kind, e.stamp_ns,
         e.n - CASE WHEN e.kind IN ('ended', 'appeared') THEN COALESCE(p.n, 0) ELSE 0 END AS n
  FROM logged e LEFT JOIN pairs p ON p.key_id = e.key_id AND p.stamp_ns = e.stamp_ns)
"""


def _difference(left: str, right: str) -> str:
    """The counts of ``left`` (``expected`` or ``actual``) that ``right`` lacks, by key."""
    return (
        f"{_COUNTED} SELECT k.agent_id, k.subject_id, k.property, k.target_id, d.kind, "
        f"d.stamp_ns, d.n FROM (SELECT * FROM {left} WHERE n > 0 "
        f"EXCEPT SELECT * FROM {right} WHERE n > 0) d "
        "JOIN fact_keys k ON k.id = d.key_id "
        "ORDER BY k.agent_id, k.id, d.stamp_ns LIMIT :limit"
    )


def _key(row: tuple[object, ...]) -> str:
    agent, subject, prop, target = row[:4]
    return f"{agent}: {subject} {prop} {target}".rstrip()


def violations(conn: Connection, *, limit: int = 20) -> list[str]:
    """The first ``limit`` violations of each invariant, one line each (empty: all hold)."""
    found: list[str] = []
    params = {"limit": limit}
    for row in conn.execute(text(_OVERLAPS + " LIMIT :limit"), params):
        end = "open" if row[5] is None else row[5]
        found.append(f"overlap: {_key(row)}: [{row[4]}, {end}) and one from {row[6]}")
    for row in conn.execute(text(_OPEN_TWICE + " LIMIT :limit"), params):
        found.append(f"open twice: {_key(row)}: {row[4]} open intervals")
    for row in conn.execute(text(_difference("expected", "actual")), params):
        found.append(
            f"missing event: {_key(row)}: {row[6]} {row[4]} boundary(ies) at "
            f"{row[5]}, not as many events"
        )
    for row in conn.execute(text(_difference("actual", "expected")), params):
        found.append(
            f"event without boundary: {_key(row)}: {row[6]} {row[4]} event(s) at "
            f"{row[5]}, not as many boundaries"
        )
    return found
