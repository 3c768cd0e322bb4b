-- The holders' keys for the self facts they take (same identity, one row per holder), for the
-- rows 45_resolve did not find.
INSERT INTO fact_keys (agent_id, subject_id, subject_owner_id, property, sub_property,
                       target_id, target_owner_id, property_type)
SELECT DISTINCT i.holder_id, k.subject_id, k.subject_owner_id, k.property, k.sub_property,
       k.target_id, k.target_owner_id, k.property_type
FROM belief_in i JOIN fact_keys k ON k.id = i.self_key
JOIN facts f {{open_fact}} ON f.key_id = k.id AND f.valid_to_ns IS NULL
WHERE i.hkey IS NULL
ON CONFLICT DO NOTHING
