INSERT INTO belief_focus (entity_id)
SELECT k.subject_id FROM belief_changed b JOIN fact_keys k ON k.id = b.key_id
UNION SELECT k.target_id FROM belief_changed b JOIN fact_keys k ON k.id = b.key_id WHERE k.target_id <> ''
ON CONFLICT DO NOTHING
