-- Settled keys: after the run, a changed key that every computed holder (not the members of a
-- group, who follow as their representative does) follows with the confidence it perceives
-- it with (the kept perception), and that no computed holder follows without perceiving it.
-- Until its followers or the kept perception change (58_frozen, 97_unsettle, 21_remember),
-- a run of a steady tick would take no step for it: 19_settled drops it from the change set.
-- since_ns: the followers began at or before :t.
DELETE FROM belief_settled WHERE key_id IN (SELECT key_id FROM belief_changed);
INSERT INTO belief_settled (key_id, since_ns)
SELECT b.key_id, {{as_int8(:t)}}
FROM belief_changed b {{pinned_join}} fact_keys k ON k.id = b.key_id
WHERE NOT EXISTS (
    SELECT 1 FROM belief_perceived p
    WHERE p.entity_id IN (k.subject_id, k.target_id) AND {{not_member(p.holder_id)}}
      AND NOT EXISTS (
        SELECT 1 FROM belief_follow w
        WHERE w.self_key = b.key_id AND w.holder_id = p.holder_id AND w.to_ns IS NULL
          AND w.pconf = (SELECT MAX(q.pconf) FROM belief_perceived q
                         WHERE q.holder_id = p.holder_id
                           AND q.entity_id IN (k.subject_id, k.target_id))))
  AND NOT EXISTS (
    SELECT 1 FROM belief_follow w
    WHERE w.self_key = b.key_id AND w.to_ns IS NULL AND {{not_member(w.holder_id)}}
      AND NOT EXISTS (SELECT 1 FROM belief_perceived p WHERE p.holder_id = w.holder_id
                        AND p.entity_id IN (k.subject_id, k.target_id)))
