INSERT INTO events (key_id, agent_id, kind, stamp_ns, value_text, value_num, confidence,
                    observability, previous_text, source, recorded_ns)
SELECT hkey, holder_id, action, CAST(:t AS bigint), value_text, value_num, confidence, observability,
       previous_text, CAST(:source AS text), CAST(:recorded AS bigint)
FROM belief_plan WHERE action <> 'refreshed'
