-- Settled keys (98_settle) leave the run's change set: while the kept perception holds
-- (pipeline.REUSE), a change of a key that every computed holder follows exactly as it
-- perceives it (and no holder that does not perceive it follows) takes no step: no holder
-- takes it (30_changes), none stops following (35_freeze). A changed value also needs its
-- followers to have begun before the write (13_late, since_ns: the run that settled it);
-- refreshed numbers (same interval) need nothing else.
DELETE FROM belief_changed WHERE EXISTS (
  SELECT 1 FROM belief_settled s WHERE s.key_id = belief_changed.key_id
    AND (belief_changed.refreshed
         OR s.since_ns < (SELECT COALESCE(f.valid_to_ns, f.valid_from_ns) FROM facts f
                          WHERE f.key_id = belief_changed.key_id
                          ORDER BY f.valid_from_ns DESC, f.id DESC LIMIT 1)))
