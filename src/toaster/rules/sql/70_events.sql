-- The holders' own events (a follower's later events are the self's, read through the views).
INSERT INTO events (key_id, agent_id, kind, stamp_ns, value_text, value_num, confidence,
                    observability, previous_text, source, recorded_ns)
SELECT hkey, holder_id, action, {{as_int8(:t)}}, value_text, value_num, confidence, observability,
       previous_text, {{as_text(:source)}}, {{as_int8(:recorded)}}
FROM belief_todo WHERE action IN ('appeared', 'changed', 'ended')
