-- New followers: their belief now equals the self's; their own event of :t is written.
INSERT INTO belief_follow (holder_id, hkey, self_key, from_ns, to_ns, events_from_ns,
                           events_to_ns, pconf)
SELECT holder_id, hkey, self_key, {{as_int8(:t)}}, NULL, {{as_int8(:t)}} + 1, NULL, pconf
FROM belief_todo WHERE action IN ('appeared', 'changed')
