-- The entities whose perception matters this tick: subjects and targets of the changed keys.
{{#postgresql}}
-- A database's first rule run: the planner has no statistics of the tables the writer has just
-- filled (a first tick registers thousands of keys), and planned the rule's joins as if they
-- held a few rows (docs/beliefs.md). Analyze them once;
-- autovacuum (or toaster db maintain) keeps them fresh afterwards.
IF (SELECT reltuples FROM pg_class WHERE oid = CAST('fact_keys' AS regclass)) < 1 THEN
  ANALYZE fact_keys, facts, belief_follow;
END IF;
-- A store's session keeps its scratch tables' pages when they are emptied (00_temp): an
-- ANALYZE of them in this session between two runs records 0 rows on N pages, and the
-- planner, which scales that density to their size, takes every later run's rows for none
-- (nested loops over thousands of rows; docs/beliefs.md). TRUNCATE forgets those statistics
-- (no pages, never analyzed); belief_changed, which holds this run's changes, is analyzed
-- instead (belief_seen is analyzed after each perception query).
IF EXISTS (SELECT 1 FROM pg_class WHERE relnamespace = pg_my_temp_schema() AND reltuples = 0
           AND relpages > 0 AND relname IN ('belief_changed', 'belief_focus', 'belief_in',
                                            'belief_todo', 'belief_freeze', 'belief_mat')) THEN
  TRUNCATE belief_focus, belief_in, belief_todo, belief_freeze, belief_mat;
  ANALYZE belief_changed;
END IF;
{{/postgresql}}
{{insert_or_ignore}} INTO belief_focus (entity_id)
SELECT k.subject_id FROM belief_changed b {{pinned_join}} fact_keys k ON k.id = b.key_id
UNION
SELECT k.target_id FROM belief_changed b {{pinned_join}} fact_keys k ON k.id = b.key_id
WHERE k.target_id <> ''
{{on_conflict_ignore}}
