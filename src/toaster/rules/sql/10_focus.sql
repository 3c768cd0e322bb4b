-- The entities whose perception matters this tick: subjects and targets of the changed keys.
{{#postgresql}}
-- A database's first rule run: the planner has no statistics of the tables the writer has just
-- filled (a first tick registers thousands of keys), and planned the rule's joins as if they
-- held a few rows (docs/beliefs.md). Analyze them once;
-- autovacuum (or toaster db maintain) keeps them fresh afterwards.
IF (SELECT reltuples FROM pg_class WHERE oid = CAST('fact_keys' AS regclass)) < 1 THEN
  ANALYZE fact_keys, facts, belief_follow;
END IF;
{{/postgresql}}
{{insert_or_ignore}} INTO belief_focus (entity_id)
SELECT k.subject_id FROM belief_changed b {{pinned_join}} fact_keys k ON k.id = b.key_id
UNION
SELECT k.target_id FROM belief_changed b {{pinned_join}} fact_keys k ON k.id = b.key_id
WHERE k.target_id <> ''
{{on_conflict_ignore}}
