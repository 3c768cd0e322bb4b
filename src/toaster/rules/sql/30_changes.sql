-- A holder takes a self change when it perceives its subject or its target: around the tick
-- (before or after) for most changes; for moves (12_moves, :moves = 1, once the phases are
-- known) before the tick for a departure and after it for an arrival. A holder that already
-- follows the key with the same perception confidence needs nothing: the views show it the
-- self's new interval and event. ({{pinned_join}}: SQLite's CROSS JOIN keeps the written join
-- order, the temporary tables having no statistics.)
INSERT INTO belief_in (holder_id, self_key, hkey, pconf)
SELECT x.holder_id, x.key_id, NULL, x.pconf
FROM (SELECT holder_id, key_id, MAX(pconf) AS pconf FROM (
        SELECT s.holder_id, b.key_id, s.pconf
        FROM belief_changed b {{pinned_join}} fact_keys k ON k.id = b.key_id
        {{pinned_join}} belief_seen s ON s.entity_id = k.subject_id AND s.phase = CASE :moves WHEN 0 THEN 'around' ELSE b.move END
        WHERE (b.move IS NOT NULL) = (:moves = 1)
        UNION ALL
        SELECT s.holder_id, b.key_id, s.pconf
        FROM belief_changed b {{pinned_join}} fact_keys k ON k.id = b.key_id
        {{pinned_join}} belief_seen s ON s.entity_id = k.target_id AND s.phase = CASE :moves WHEN 0 THEN 'around' ELSE b.move END
        WHERE (b.move IS NOT NULL) = (:moves = 1)
        UNION ALL
        -- a departure, seen by who sees the subject elsewhere after it
        SELECT s.holder_id, b.key_id, s.pconf
        FROM belief_changed b {{pinned_join}} fact_keys k ON k.id = b.key_id
        {{pinned_join}} belief_seen s ON s.entity_id = k.subject_id AND s.phase = 'after'
        WHERE b.move = 'before' AND :moves = 1
      ) AS seen GROUP BY holder_id, key_id) AS x
WHERE NOT EXISTS (
  SELECT 1 FROM belief_follow w
  WHERE w.self_key = x.key_id AND w.holder_id = x.holder_id AND w.to_ns IS NULL
    AND w.pconf = x.pconf)
