-- The holders' keys already known for the self keys they take (50_keys adds the others).
UPDATE belief_in SET hkey = (
  SELECT hk.id FROM fact_keys k JOIN fact_keys hk ON hk.agent_id = belief_in.holder_id
    AND hk.subject_id = k.subject_id AND hk.subject_owner_id = k.subject_owner_id
    AND hk.property = k.property AND hk.sub_property = k.sub_property
    AND hk.target_id = k.target_id AND hk.target_owner_id = k.target_owner_id
  WHERE k.id = belief_in.self_key)
WHERE hkey IS NULL
