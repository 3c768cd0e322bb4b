-- Frozen followers: their own interval continues where the period ends.
INSERT INTO facts (key_id, value_text, value_num, confidence, observability, valid_from_ns,
                   recorded_ns, source)
SELECT hkey, value_text, value_num, confidence, observability, cut_ns, {{as_int8(:recorded)}}, {{as_text(:source)}}
FROM belief_freeze WHERE value_text IS NOT NULL;
UPDATE belief_follow SET to_ns = z.cut_ns, events_to_ns = z.cut_ns FROM belief_freeze z
WHERE z.follow_id = belief_follow.id
  -- (the IN list: SQLite, with no statistics of the scratch table, otherwise scans every period)
  AND belief_follow.id IN (SELECT follow_id FROM belief_freeze);
-- The keys whose followers stop are no longer settled (98_settle).
DELETE FROM belief_settled WHERE key_id IN (
  SELECT w.self_key FROM belief_freeze z {{pinned_join}} belief_follow w ON w.id = z.follow_id);
-- (applied: 13_late's periods are frozen before the changes are taken, 35_freeze's after)
DELETE FROM belief_freeze
