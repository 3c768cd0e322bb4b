-- Holder intervals that end: a changed value (a new one is followed or opened) or an ended fact.
-- (The open interval is found through the subquery: SQLite allows no INDEXED BY on the target
-- of an UPDATE inside a trigger.)
UPDATE facts SET valid_to_ns = :t
WHERE id IN (SELECT f.id FROM belief_todo b {{pinned_join}} facts f {{open_fact}}
               ON f.key_id = b.hkey AND f.valid_to_ns IS NULL
             WHERE b.action IN ('changed', 'ended'))
