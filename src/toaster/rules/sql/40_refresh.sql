-- Seeing again: entities a holder perceives after the tick but not before. Observable self facts
-- about them (not hidden in a closed container) are learnt with confidence x observability.
INSERT INTO belief_in (holder_id, self_key, hkey, pconf, seen_again)
WITH RECURSIVE
cfg_in(p) AS (SELECT value FROM {{setting_list(containment)}}),
closed(e) AS (
  SELECT k.subject_id FROM fact_keys k JOIN facts f ON f.key_id = k.id AND f.valid_to_ns IS NULL
  WHERE k.agent_id = :self AND f.value_text = 'true'
    AND k.property = {{setting_text(closed)}}
),
inside(e, c) AS (
  SELECT k.subject_id, k.target_id FROM fact_keys k JOIN facts f ON f.key_id = k.id AND f.valid_to_ns IS NULL
  WHERE k.agent_id = :self AND k.property IN (SELECT p FROM cfg_in) AND f.value_text <> 'false'
),
hidden(e) AS (
  SELECT e FROM inside WHERE c IN (SELECT e FROM closed)
  UNION SELECT i.e FROM inside i JOIN hidden h ON i.c = h.e
),
newly(holder_id, entity_id, pconf) AS (
  SELECT a.holder_id, a.entity_id, a.pconf FROM belief_seen a
  WHERE a.phase = 'after' AND NOT EXISTS (
    SELECT 1 FROM belief_seen b WHERE b.phase = 'before'
      AND b.holder_id = a.holder_id AND b.entity_id = a.entity_id)
  -- the actor of a change handles its subject: it sees where it is now, and that it is no
  -- longer wherever it believed it was
  UNION
  SELECT b.actor_id, k.subject_id, 1.0 FROM belief_changed b JOIN fact_keys k ON k.id = b.key_id
  WHERE b.actor_id IS NOT NULL
),
-- A move is seen where it happens (12_moves): who perceives a thing arrive (after the tick)
-- sees where it is now, and who perceives it leave (before the tick) saw where it was; either
-- way it is no longer wherever else the holder believed it was (its other places end), even
-- for a holder that perceived it before too, or only before through the actor of the move (A
-- saw B see it leave).
moved(holder_id, entity_id, pconf) AS (
  SELECT s.holder_id, k.subject_id, s.pconf
  FROM belief_changed b {{pinned_join}} fact_keys k ON k.id = b.key_id
  {{pinned_join}} belief_seen s ON s.entity_id = k.subject_id AND s.phase = b.move
  WHERE b.move IS NOT NULL
  UNION
  SELECT s.holder_id, k.subject_id, s.pconf
  FROM belief_changed b {{pinned_join}} fact_keys k ON k.id = b.key_id
  {{pinned_join}} belief_seen s ON s.entity_id = k.target_id AND s.phase = b.move
  WHERE b.move IS NOT NULL
),
stale(holder_id, entity_id, pconf) AS (
  SELECT holder_id, entity_id, pconf FROM newly UNION SELECT holder_id, entity_id, pconf FROM moved
),
-- Containers whose closed fact ended at :t, with the holders who see them afterwards: opening
-- a container shows its content (and that what was believed inside is no longer there).
opened(holder_id, entity_id, pconf) AS (
  SELECT a.holder_id, a.entity_id, a.pconf FROM belief_seen a
  WHERE a.phase = 'after' AND a.entity_id IN (
    SELECT k.subject_id FROM belief_changed b JOIN fact_keys k ON k.id = b.key_id
    JOIN facts f ON f.key_id = k.id AND f.valid_to_ns = :t
    WHERE k.agent_id = :self AND f.value_text = 'true' AND k.property = {{setting_text(closed)}})
)
SELECT n.holder_id, k.id, NULL, n.pconf * f.observability, 1
FROM newly n
{{pinned_join}} fact_keys k ON k.agent_id = :self AND k.subject_id = n.entity_id
JOIN facts f ON f.key_id = k.id AND f.valid_to_ns IS NULL
WHERE f.observability > 0 AND {{not_hidden(n.entity_id)}}
UNION ALL
SELECT n.holder_id, NULL, hk.id, n.pconf, 1
FROM stale n
JOIN fact_keys hk ON hk.agent_id = n.holder_id AND hk.subject_id = n.entity_id
JOIN facts hf ON hf.key_id = hk.id AND hf.valid_to_ns IS NULL AND hf.observability > 0
WHERE {{not_hidden(hk.subject_id)}}
  AND NOT EXISTS ({{self_holds(hk)}})
UNION ALL
SELECT n.holder_id, NULL, hk.id, n.pconf, 1
FROM newly n
JOIN fact_keys hk {{keys_by_target}} ON hk.agent_id = n.holder_id AND hk.target_id = n.entity_id
  AND hk.subject_id <> n.entity_id
  AND hk.property IN (SELECT value FROM {{setting_list(refute_by_target)}})
JOIN facts hf ON hf.key_id = hk.id AND hf.valid_to_ns IS NULL AND hf.observability > 0
WHERE {{not_hidden(hk.subject_id)}}
  AND NOT EXISTS ({{self_holds(hk)}})
UNION ALL
SELECT o.holder_id, k.id, NULL, o.pconf * f.observability, 1
FROM opened o
{{pinned_join}} fact_keys k {{keys_by_target}} ON k.agent_id = :self AND k.target_id = o.entity_id
  AND k.property IN (SELECT p FROM cfg_in)
JOIN facts f ON f.key_id = k.id AND f.valid_to_ns IS NULL
WHERE f.observability > 0
UNION ALL
SELECT o.holder_id, NULL, hk.id, o.pconf, 1
FROM opened o
JOIN fact_keys hk {{keys_by_target}} ON hk.agent_id = o.holder_id AND hk.target_id = o.entity_id
  AND hk.property IN (SELECT p FROM cfg_in)
JOIN facts hf ON hf.key_id = hk.id AND hf.valid_to_ns IS NULL AND hf.observability > 0
WHERE NOT EXISTS ({{self_holds(hk)}})
