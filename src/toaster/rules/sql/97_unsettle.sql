-- The keys whose followers changed in this run (new followers, new confidences) are no longer
-- settled (98_settle decides again for the run's changes).
DELETE FROM belief_settled WHERE key_id IN (
  SELECT self_key FROM belief_todo WHERE self_key IS NOT NULL
  UNION SELECT w.self_key FROM belief_todo t {{pinned_join}} belief_follow w ON w.id = t.follow_id)
