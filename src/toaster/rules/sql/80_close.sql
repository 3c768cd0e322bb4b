-- Holder intervals that end: a changed value (a new one is followed or opened) or an ended fact.
-- (SQLite: the open interval is found through a subquery, as SQLite allows no INDEXED BY on the
-- target of an UPDATE inside a trigger.)
UPDATE facts SET valid_to_ns = :t
{{#sqlite}}
WHERE id IN (SELECT f.id FROM belief_todo b CROSS JOIN facts f INDEXED BY uq_facts_open_key
               ON f.key_id = b.hkey AND f.valid_to_ns IS NULL
             WHERE b.action IN ('changed', 'ended'))
{{/sqlite}}
{{#postgresql}}
WHERE valid_to_ns IS NULL
  AND key_id IN (SELECT hkey FROM belief_todo WHERE action IN ('changed', 'ended'))
{{/postgresql}}
