INSERT INTO facts (key_id, value_text, value_num, confidence, observability, valid_from_ns,
                   recorded_ns, source)
SELECT hkey, value_text, value_num, confidence, observability, CAST(:t AS bigint), CAST(:recorded AS bigint), CAST(:source AS text)
FROM belief_plan WHERE action IN ('appeared', 'changed')
