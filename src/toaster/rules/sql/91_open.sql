-- With the setting share_rows = false (instead of 90_follow): holders that take a change get
-- their own interval, as the straightforward design does (kept as the benchmarks' baseline).
INSERT INTO facts (key_id, value_text, value_num, confidence, observability, valid_from_ns,
                   recorded_ns, source)
SELECT hkey, value_text, value_num, confidence, observability, {{as_int8(:t)}},
       {{as_int8(:recorded)}}, {{as_text(:source)}}
FROM belief_todo WHERE action IN ('appeared', 'changed')
