-- Copy the followed periods listed in belief_mat into the holders' own rows (intervals and
-- events exactly as the views show them: the followed-period macros, see sqltext.FOLLOWED)
-- and drop the periods. Used before a direct write to a holder, before the self agent's facts
-- are emptied, and by downgrades.
-- The holders' followed keys change: the groups of holders (96_regroup) no longer hold.
{{ungroup}} AND EXISTS (SELECT 1 FROM belief_mat);
INSERT INTO facts (key_id, value_text, value_num, confidence, observability, valid_from_ns,
                   valid_to_ns, recorded_ns, source)
SELECT w.hkey, f.value_text, f.value_num, {{followed_conf(f.confidence)}}, f.observability,
       {{followed_from}}, {{followed_to}}, f.recorded_ns, 'beliefs'
FROM belief_mat m JOIN belief_follow w ON w.id = m.follow_id
JOIN facts f ON f.key_id = w.self_key AND {{followed_facts}};
INSERT INTO events (key_id, agent_id, kind, stamp_ns, value_text, value_num, confidence,
                    observability, previous_text, source, recorded_ns)
SELECT w.hkey, w.holder_id, e.kind, e.stamp_ns, e.value_text, e.value_num,
       {{followed_conf(e.confidence)}}, e.observability, e.previous_text, 'beliefs',
       e.recorded_ns
FROM belief_mat m JOIN belief_follow w ON w.id = m.follow_id
JOIN events e ON e.key_id = w.self_key AND {{followed_events}};
DELETE FROM belief_follow WHERE id IN (SELECT follow_id FROM belief_mat);
DELETE FROM belief_mat
