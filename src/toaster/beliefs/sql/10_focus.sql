-- The entities whose perception matters this tick: subjects and targets of the changed keys.
{{insert_or_ignore}} INTO belief_focus (entity_id)
SELECT k.subject_id FROM belief_changed b JOIN fact_keys k ON k.id = b.key_id
UNION SELECT k.target_id FROM belief_changed b JOIN fact_keys k ON k.id = b.key_id WHERE k.target_id <> ''
{{on_conflict_ignore}}
