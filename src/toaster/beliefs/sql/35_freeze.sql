-- A follower that does not perceive a change of its key (where it happens, 12_moves) stops
-- following: its belief keeps the interval the self held just before the tick (a false belief
-- from then on). The period ends
-- where that interval started (or where the last one ended), so that the holder's own row
-- continues it without a split (a period may end empty: it still holds its first event).
INSERT INTO belief_freeze (follow_id, hkey, from_ns, cut_ns, value_text, value_num, confidence,
                           observability)
WITH stopped AS MATERIALIZED (
  SELECT w.id, w.hkey, w.from_ns, w.pconf, b.key_id, b.refreshed, b.prev_num, b.prev_conf,
         b.prev_obs
  FROM belief_changed b {{pinned_join}} fact_keys k ON k.id = b.key_id
  {{pinned_join}} belief_follow w ON w.self_key = b.key_id AND w.to_ns IS NULL
  WHERE b.move IS NULL
    AND NOT EXISTS (SELECT 1 FROM belief_seen s WHERE s.entity_id = k.subject_id
                      AND s.phase = 'around' AND s.holder_id = w.holder_id)
    AND NOT EXISTS (SELECT 1 FROM belief_seen s WHERE s.entity_id = k.target_id
                      AND s.phase = 'around' AND s.holder_id = w.holder_id)
  UNION ALL
  -- moves (12_moves): a departure also by who sees the subject elsewhere after it
  SELECT w.id, w.hkey, w.from_ns, w.pconf, b.key_id, b.refreshed, b.prev_num, b.prev_conf,
         b.prev_obs
  FROM belief_changed b {{pinned_join}} fact_keys k ON k.id = b.key_id
  {{pinned_join}} belief_follow w ON w.self_key = b.key_id AND w.to_ns IS NULL
  WHERE b.move IS NOT NULL
    AND NOT EXISTS (SELECT 1 FROM belief_seen s WHERE s.entity_id = k.subject_id
                      AND s.phase = b.move AND s.holder_id = w.holder_id)
    AND NOT EXISTS (SELECT 1 FROM belief_seen s WHERE s.entity_id = k.target_id
                      AND s.phase = b.move AND s.holder_id = w.holder_id)
    AND NOT (b.move = 'before' AND EXISTS (
      SELECT 1 FROM belief_seen s WHERE s.entity_id = k.subject_id AND s.phase = 'after'
        AND s.holder_id = w.holder_id))
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
