-- The holders' keys already known for the self keys they take (50_keys adds the others).
{{#sqlite}}
UPDATE belief_in SET hkey = (
  SELECT hk.id FROM fact_keys k JOIN fact_keys hk ON hk.agent_id = belief_in.holder_id
    AND hk.subject_id = k.subject_id AND hk.subject_owner_id = k.subject_owner_id
    AND hk.property = k.property AND hk.sub_property = k.sub_property
    AND hk.target_id = k.target_id AND hk.target_owner_id = k.target_owner_id
  WHERE k.id = belief_in.self_key)
WHERE hkey IS NULL
{{/sqlite}}
{{#postgresql}}
-- With belief_in's real size known, a join (not a subquery per row, which a first tick on
-- tables with few statistics planned as a scan of fact_keys per row of belief_in).
ANALYZE belief_in;
UPDATE belief_in SET hkey = hk.id
FROM fact_keys k, fact_keys hk
WHERE belief_in.hkey IS NULL AND k.id = belief_in.self_key
  AND hk.agent_id = belief_in.holder_id
  AND hk.subject_id = k.subject_id AND hk.subject_owner_id = k.subject_owner_id
  AND hk.property = k.property AND hk.sub_property = k.sub_property
  AND hk.target_id = k.target_id AND hk.target_owner_id = k.target_owner_id
{{/postgresql}}
