-- A holder takes the largest perception confidence of a key. 30_changes left out the changes
-- a follower perceived with its current confidence: a seeing-again row with no more than that
-- confidence must not lower it.
DELETE FROM belief_in
WHERE seen_again = 1 AND self_key IN (SELECT key_id FROM belief_changed)
  AND NOT EXISTS (SELECT 1 FROM belief_in c WHERE c.seen_again = 0
                    AND c.holder_id = belief_in.holder_id AND c.self_key = belief_in.self_key)
  AND EXISTS (SELECT 1 FROM belief_follow w WHERE w.self_key = belief_in.self_key
                AND w.holder_id = belief_in.holder_id AND w.to_ns IS NULL
                AND w.pconf >= belief_in.pconf)
