-- Holder intervals refreshed in place: same value, new number, confidence or observability.
UPDATE facts
SET value_num = p.value_num, confidence = p.confidence, observability = p.observability
FROM belief_todo p
{{#sqlite}}
WHERE facts.id IN (SELECT f.id FROM belief_todo b CROSS JOIN facts f INDEXED BY uq_facts_open_key
                     ON f.key_id = b.hkey AND f.valid_to_ns IS NULL
                   WHERE b.action = 'refreshed')
  AND facts.key_id = p.hkey AND p.action = 'refreshed'
{{/sqlite}}
{{#postgresql}}
WHERE facts.key_id = p.hkey AND facts.valid_to_ns IS NULL AND p.action = 'refreshed'
{{/postgresql}}
