-- New perception confidences (see 60_plan).
UPDATE belief_follow SET pconf = p.pconf FROM belief_todo p
WHERE p.follow_id = belief_follow.id AND p.action = 'repconf' AND p.split_ns IS NULL;
UPDATE belief_follow SET to_ns = p.split_ns,
  events_to_ns = CASE WHEN p.split_ns = :t THEN p.split_ns - 1 ELSE p.split_ns END
FROM belief_todo p
WHERE p.follow_id = belief_follow.id AND p.action = 'repconf' AND p.split_ns IS NOT NULL;
INSERT INTO belief_follow (holder_id, hkey, self_key, from_ns, to_ns, events_from_ns,
                           events_to_ns, pconf)
SELECT holder_id, hkey, self_key, split_ns, NULL,
       CASE WHEN split_ns = {{as_int8(:t)}} THEN split_ns ELSE split_ns + 1 END, NULL, pconf
FROM belief_todo WHERE action = 'repconf' AND split_ns IS NOT NULL
