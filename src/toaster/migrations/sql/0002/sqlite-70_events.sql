INSERT INTO events (key_id, agent_id, kind, stamp_ns, value_text, value_num, confidence,
                    observability, previous_text, source, recorded_ns)
SELECT hkey, holder_id, action, :t, value_text, value_num, confidence, observability,
       previous_text, :source, :recorded
FROM belief_plan WHERE action <> 'refreshed'
