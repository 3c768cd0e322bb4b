-- Holder intervals refreshed in place: same value, new number, confidence or observability.
-- The numbers they held until :t are kept as a sample, as the store keeps a self interval's
-- (as-of queries read them: without it a holder's past showed the new numbers).
INSERT INTO fact_samples (fact_id, until_ns, value_num, confidence, observability)
SELECT f.id, {{as_int8(:t)}}, f.value_num, f.confidence, f.observability
FROM belief_todo b {{pinned_join}} facts f {{open_fact}} ON f.key_id = b.hkey AND f.valid_to_ns IS NULL
WHERE b.action = 'refreshed'
ON CONFLICT DO NOTHING;
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
