-- Holder intervals refreshed in place: same value, new number, confidence or observability.
UPDATE facts
SET value_num = p.value_num, confidence = p.confidence, observability = p.observability
FROM belief_todo p
WHERE facts.id IN (SELECT f.id FROM belief_todo b {{pinned_join}} facts f {{open_fact}}
                     ON f.key_id = b.hkey AND f.valid_to_ns IS NULL
                   WHERE b.action = 'refreshed')
  AND facts.key_id = p.hkey AND p.action = 'refreshed'
