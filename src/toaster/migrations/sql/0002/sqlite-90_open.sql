INSERT INTO facts (key_id, value_text, value_num, confidence, observability, valid_from_ns,
                   recorded_ns, source)
SELECT hkey, value_text, value_num, confidence, observability, :t, :recorded, :source
FROM belief_plan WHERE action IN ('appeared', 'changed')
