-- Moves: a change of where something is (a copresence or containment fact: IsInRoom, IsIn,
-- IsOn) is seen where it happens. A key whose interval ended at :t with none open after is a
-- departure, seen by who perceived the subject or target before the tick; one that started at :t
-- with none ending then is an arrival, seen by who perceives them after. Other changes are seen
-- by who perceives them before or after ('around').
UPDATE belief_changed SET move = CASE
    WHEN NOT EXISTS (SELECT 1 FROM facts o {{open_fact}} WHERE o.key_id = belief_changed.key_id
                     AND o.valid_to_ns IS NULL) THEN 'before'
    WHEN NOT EXISTS (SELECT 1 FROM facts e WHERE e.key_id = belief_changed.key_id
                     AND e.valid_to_ns = :t) THEN 'after' END
WHERE NOT refreshed AND EXISTS (
  SELECT 1 FROM fact_keys k WHERE k.id = belief_changed.key_id
    AND (k.property IN (SELECT value FROM {{setting_list(copresence)}})
         OR k.property IN (SELECT value FROM {{setting_list(containment)}})))
