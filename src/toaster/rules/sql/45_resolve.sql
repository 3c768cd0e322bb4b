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
-- Each row's keys found by index, in the written order (belief_in -> its self key by id ->
-- the holder's key by uq_fact_keys_identity; OFFSET 0 keeps the order from being merged into
-- the update's join): with the target table free to join first, a database with stale
-- statistics planned a hash join of belief_in with every key of each holder, then a scan by
-- subject per pair (a cost growing with the number of robots whose keys share subjects;
-- docs/beliefs.md).
UPDATE belief_in SET hkey = r.hkey
FROM (SELECT i.holder_id, i.self_key, hk.id AS hkey
      FROM belief_in i
      JOIN fact_keys k ON k.id = i.self_key
      JOIN fact_keys hk ON hk.agent_id = i.holder_id
        AND hk.subject_id = k.subject_id AND hk.subject_owner_id = k.subject_owner_id
        AND hk.property = k.property AND hk.sub_property = k.sub_property
        AND hk.target_id = k.target_id AND hk.target_owner_id = k.target_owner_id
      WHERE i.hkey IS NULL
      OFFSET 0) AS r
WHERE belief_in.hkey IS NULL AND belief_in.self_key = r.self_key
  AND belief_in.holder_id = r.holder_id
{{/postgresql}}
