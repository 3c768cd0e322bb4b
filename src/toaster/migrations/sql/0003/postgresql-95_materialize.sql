-- Copy the followed periods listed in belief_mat into the holders' own rows (intervals and
-- events exactly as the views show them) and drop the periods. Used before a direct write to a
-- holder, before the self agent's facts are emptied, and by downgrades.
INSERT INTO facts (key_id, value_text, value_num, confidence, observability, valid_from_ns,
                   valid_to_ns, recorded_ns, source)
SELECT w.hkey, f.value_text, f.value_num, LEAST(1.0, f.confidence * w.pconf), f.observability,
       GREATEST(f.valid_from_ns, w.from_ns),
       CASE WHEN w.to_ns IS NULL THEN f.valid_to_ns WHEN f.valid_to_ns IS NULL THEN w.to_ns
            ELSE LEAST(f.valid_to_ns, w.to_ns) END,
       f.recorded_ns, 'beliefs'
FROM belief_mat m JOIN belief_follow w ON w.id = m.follow_id
JOIN facts f ON f.key_id = w.self_key
  AND (w.to_ns IS NULL OR (f.valid_from_ns < w.to_ns AND w.to_ns > w.from_ns))
  AND (f.valid_to_ns IS NULL OR f.valid_to_ns > w.from_ns);
INSERT INTO events (key_id, agent_id, kind, stamp_ns, value_text, value_num, confidence,
                    observability, previous_text, source, recorded_ns)
SELECT w.hkey, w.holder_id, e.kind, e.stamp_ns, e.value_text, e.value_num,
       LEAST(1.0, e.confidence * w.pconf), e.observability, e.previous_text, 'beliefs',
       e.recorded_ns
FROM belief_mat m JOIN belief_follow w ON w.id = m.follow_id
JOIN events e ON e.key_id = w.self_key AND e.kind <> 'event'
  AND e.stamp_ns >= w.events_from_ns AND (w.events_to_ns IS NULL OR e.stamp_ns <= w.events_to_ns);
DELETE FROM belief_follow WHERE id IN (SELECT follow_id FROM belief_mat);
DELETE FROM belief_mat
