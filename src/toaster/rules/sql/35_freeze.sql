-- A follower that does not perceive a change of its key (where it happens, 12_moves) stops
-- following: its belief keeps the interval the self held just before the tick (a false belief
-- from then on). The period ends
-- where that interval started (or where the last one ended), so that the holder's own row
-- continues it without a split (a period may end empty: it still holds its first event).
INSERT INTO belief_freeze (follow_id, hkey, from_ns, cut_ns, value_text, value_num, confidence,
                           observability)
WITH
-- The open periods of the changed keys, for the holders whose perception is computed: every
-- holder, or (grouped holders, 96_regroup) the representatives and the holders of no group,
-- looked up one by one rather than by scanning the members' periods.
computed_holders(id) AS MATERIALIZED (
  SELECT id FROM holders WHERE EXISTS (SELECT 1 FROM belief_groups) AND {{not_member(id)}}
),
fw AS MATERIALIZED (
  SELECT w.id, w.hkey, w.from_ns, w.pconf, w.holder_id, b.key_id
  FROM belief_changed b {{pinned_join}} belief_follow w ON w.self_key = b.key_id AND w.to_ns IS NULL
  WHERE NOT EXISTS (SELECT 1 FROM belief_groups)
  UNION ALL
  SELECT w.id, w.hkey, w.from_ns, w.pconf, w.holder_id, b.key_id
  FROM belief_changed b CROSS JOIN computed_holders r
{{#sqlite}}
  CROSS JOIN belief_follow w ON w.self_key = b.key_id AND w.holder_id = r.id AND w.to_ns IS NULL
{{/sqlite}}
{{#postgresql}}
  -- (one index probe per key and holder: OFFSET 0 keeps the subquery a loop, which the
  -- planner otherwise merged with a scan of every followed period)
  CROSS JOIN LATERAL (SELECT * FROM belief_follow w WHERE w.self_key = b.key_id
                        AND w.holder_id = r.id AND w.to_ns IS NULL OFFSET 0) AS w
{{/postgresql}}
),
computed AS MATERIALIZED (
  SELECT w.id, w.hkey, w.from_ns, w.pconf, w.holder_id, b.key_id, b.refreshed, b.prev_num,
         b.prev_conf, b.prev_obs
  FROM fw w {{pinned_join}} belief_changed b ON b.key_id = w.key_id
  {{pinned_join}} fact_keys k ON k.id = b.key_id
  WHERE b.move IS NULL
    AND NOT EXISTS (SELECT 1 FROM belief_seen s WHERE s.entity_id = k.subject_id
                      AND s.phase = 'around' AND s.holder_id = w.holder_id)
    AND NOT EXISTS (SELECT 1 FROM belief_seen s WHERE s.entity_id = k.target_id
                      AND s.phase = 'around' AND s.holder_id = w.holder_id)
  UNION ALL
  -- moves (12_moves): a departure also by who sees the subject elsewhere after it
  SELECT w.id, w.hkey, w.from_ns, w.pconf, w.holder_id, b.key_id, b.refreshed, b.prev_num,
         b.prev_conf, b.prev_obs
  FROM fw w {{pinned_join}} belief_changed b ON b.key_id = w.key_id
  {{pinned_join}} fact_keys k ON k.id = b.key_id
  WHERE b.move IS NOT NULL
    AND NOT EXISTS (SELECT 1 FROM belief_seen s WHERE s.entity_id = k.subject_id
                      AND s.phase = b.move AND s.holder_id = w.holder_id)
    AND NOT EXISTS (SELECT 1 FROM belief_seen s WHERE s.entity_id = k.target_id
                      AND s.phase = b.move AND s.holder_id = w.holder_id)
    AND NOT (b.move = 'before' AND EXISTS (
      SELECT 1 FROM belief_seen s WHERE s.entity_id = k.subject_id AND s.phase = 'after'
        AND s.holder_id = w.holder_id))
),
-- The members of a group stop with their representative (they follow the same keys).
stopped AS (
  SELECT id, hkey, from_ns, pconf, key_id, refreshed, prev_num, prev_conf, prev_obs
  FROM computed
  UNION ALL
  SELECT w.id, w.hkey, w.from_ns, w.pconf, c.key_id, c.refreshed, c.prev_num, c.prev_conf,
         c.prev_obs
  FROM computed c {{pinned_join}} belief_groups g ON g.rep_id = c.holder_id AND g.holder_id <> g.rep_id
  {{pinned_join}} belief_follow w ON w.self_key = c.key_id AND w.holder_id = g.holder_id
    AND w.to_ns IS NULL
)
SELECT z.id, z.hkey, z.from_ns,
       CASE WHEN l.id IS NULL THEN z.from_ns
            WHEN l.valid_to_ns IS NULL OR l.valid_to_ns >= :t THEN {{hi}}(l.valid_from_ns, z.from_ns)
            ELSE {{hi}}(l.valid_to_ns, z.from_ns) END,
       CASE WHEN l.valid_to_ns IS NULL OR l.valid_to_ns >= :t THEN l.value_text END,
       CASE WHEN z.refreshed THEN z.prev_num ELSE l.value_num END,
       {{lo}}(1.0, CASE WHEN z.refreshed THEN z.prev_conf ELSE l.confidence END * z.pconf),
       CASE WHEN z.refreshed THEN z.prev_obs ELSE l.observability END
FROM stopped z
LEFT JOIN facts l ON l.id = (
  SELECT f2.id FROM facts f2 WHERE f2.key_id = z.key_id AND f2.valid_from_ns < :t
  ORDER BY f2.valid_from_ns DESC, f2.id DESC LIMIT 1)
