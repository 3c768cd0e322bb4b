-- A holder takes a self change when it perceives its subject or its target.
INSERT INTO belief_in (holder_id, self_key, hkey, pconf)
SELECT s.holder_id, b.key_id, NULL, MAX(s.pconf)
FROM belief_keys b JOIN fact_keys k ON k.id = b.key_id
JOIN belief_seen s ON s.phase = 'around' AND s.entity_id IN (k.subject_id, k.target_id)
GROUP BY s.holder_id, b.key_id
