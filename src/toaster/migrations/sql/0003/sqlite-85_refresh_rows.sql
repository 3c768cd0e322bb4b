UPDATE facts INDEXED BY uq_facts_open_key
SET value_num = p.value_num, confidence = p.confidence, observability = p.observability
FROM belief_todo p
WHERE facts.key_id = p.hkey AND facts.valid_to_ns IS NULL AND p.action = 'refreshed'
