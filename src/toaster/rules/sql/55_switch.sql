-- Several self agents (robots) may hold the same fact: a holder that follows one robot's key
-- and takes a change of another's stops following the first (its current belief becomes its
-- own row, applied by 58_frozen before the plan compares with it). The followed key did not
-- change in this run: the holder's belief is the followed interval that holds *at* :t, one
-- that an earlier run of the same instant started included (with "before :t" such a holder
-- seemed to believe nothing, and took the same fact again with a second event of :t).
INSERT INTO belief_freeze (follow_id, hkey, from_ns, cut_ns, value_text, value_num, confidence,
                           observability)
SELECT w.id, w.hkey, w.from_ns,
       CASE WHEN l.id IS NULL THEN w.from_ns
            WHEN l.valid_to_ns IS NULL OR l.valid_to_ns > :t THEN {{hi}}(l.valid_from_ns, w.from_ns)
            ELSE {{hi}}(l.valid_to_ns, w.from_ns) END,
       CASE WHEN l.valid_to_ns IS NULL OR l.valid_to_ns > :t THEN l.value_text END,
       l.value_num, {{lo}}(1.0, l.confidence * w.pconf), l.observability
FROM (SELECT DISTINCT hkey, self_key FROM belief_in
      WHERE hkey IS NOT NULL AND self_key IS NOT NULL) AS i
JOIN belief_follow w ON w.hkey = i.hkey AND w.to_ns IS NULL AND w.self_key <> i.self_key
LEFT JOIN facts l ON l.id = (
  SELECT f2.id FROM facts f2 WHERE f2.key_id = w.self_key AND f2.valid_from_ns <= :t
  ORDER BY f2.valid_from_ns DESC, f2.id DESC LIMIT 1)
WHERE w.id NOT IN (SELECT follow_id FROM belief_freeze)
