-- A late write (a robot or SQL client whose change is older than the rules' clock: its run
-- happens at the clock's time :t) may end a robot's interval at a time before some holders
-- began following it: they took it at the clock's time, after it had ended in the robot's
-- past. Their followed period would show nothing and their event of its start would have no
-- interval. Such a period is frozen where it began (applied by 58_frozen at once, before the
-- holders take the run's changes): the holder's own row continues it with the robot's value,
-- so a holder that perceives the change takes it (the plan ends the row at :t) and one that
-- does not keeps it (a false belief), as for any own row. A run's changes are written at one
-- time (a key's latest boundary): only keys written at or before :t are looked at (at :t: one
-- robot's writes at one time share its instant, and the holders may have begun following at
-- :t, in an earlier run of that instant, a fact a later write ends there; revision 0015).
INSERT INTO belief_freeze (follow_id, hkey, from_ns, cut_ns, value_text, value_num, confidence,
                           observability)
WITH
written AS MATERIALIZED (
  SELECT b.key_id, (SELECT COALESCE(f.valid_to_ns, f.valid_from_ns) FROM facts f
                    WHERE f.key_id = b.key_id
                    ORDER BY f.valid_from_ns DESC, f.id DESC LIMIT 1) AS at_ns
  FROM belief_changed b WHERE NOT b.refreshed
),
-- the interval the late write closed: it ends where the write happened (an empty one too: a
-- fact asserted and retracted at one time by two writes, whose followers began following it
-- at that time)
late AS MATERIALIZED (
  SELECT x.key_id, x.at_ns,
         (SELECT f.id FROM facts f WHERE f.key_id = x.key_id AND f.valid_from_ns <= x.at_ns
            AND f.valid_to_ns = x.at_ns
          ORDER BY f.valid_from_ns DESC, f.id DESC LIMIT 1) AS fact_id
  FROM written x WHERE x.at_ns <= :t
),
closed AS MATERIALIZED (
  SELECT l.key_id, l.value_text, l.value_num, l.confidence, l.observability, l.valid_to_ns
{{#sqlite}}
  FROM late x CROSS JOIN facts l ON l.id = x.fact_id
{{/sqlite}}
{{#postgresql}}
  -- (index probes, one per late key and its followers: OFFSET 0 keeps each subquery a loop,
  -- which the planner otherwise made a hash join over every fact or every open period)
  FROM late x CROSS JOIN LATERAL (SELECT * FROM facts l WHERE l.id = x.fact_id OFFSET 0) AS l
{{/postgresql}}
  WHERE l.valid_to_ns = x.at_ns
)
SELECT w.id, w.hkey, w.from_ns, w.from_ns, c.value_text, c.value_num,
       {{lo}}(1.0, c.confidence * w.pconf), c.observability
{{#sqlite}}
FROM closed c CROSS JOIN belief_follow w ON w.self_key = c.key_id AND w.to_ns IS NULL
{{/sqlite}}
{{#postgresql}}
FROM closed c CROSS JOIN LATERAL (SELECT * FROM belief_follow w WHERE w.self_key = c.key_id
                                    AND w.to_ns IS NULL OFFSET 0) AS w
{{/postgresql}}
WHERE c.valid_to_ns <= w.from_ns
