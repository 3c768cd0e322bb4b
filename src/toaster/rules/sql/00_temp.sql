-- PostgreSQL only: the session's own scratch tables of a rule run, shadowing the shared ones of
-- the schema (belief_changed, belief_focus, ... in toaster.db.schema) so that concurrent writers
-- never share rows; SQLite (one writer at a time) uses the schema's tables, the only ones its
-- triggers can read. Emptied by 99_clear. For the SQL clients whose triggers create them they
-- are also truncated at commit (ON COMMIT DELETE ROWS): temporary tables are never vacuumed,
-- so the dead rows of DELETE would pile up tick after tick in them and their indexes, slowing
-- every run (docs/beliefs.md). A store's session creates them first,
-- without it, and vacuums them every few runs (toaster.rules.hook): truncating
-- them at each commit cost as much as the run, while it held the rules' clock.
{{#postgresql}}
CREATE TEMP TABLE IF NOT EXISTS belief_changed (key_id bigint PRIMARY KEY, refreshed boolean NOT NULL, prev_num float8, prev_conf float8, prev_obs float8, move text, actor_id text) ON COMMIT DELETE ROWS;
CREATE TEMP TABLE IF NOT EXISTS belief_focus (entity_id text PRIMARY KEY) ON COMMIT DELETE ROWS;
CREATE TEMP TABLE IF NOT EXISTS belief_seen (holder_id text, entity_id text, phase text, pconf float8) ON COMMIT DELETE ROWS;
CREATE INDEX IF NOT EXISTS belief_seen_entity_holder ON belief_seen (entity_id, phase, holder_id);
CREATE TEMP TABLE IF NOT EXISTS belief_in (holder_id text, self_key bigint, hkey bigint, pconf float8, seen_again integer NOT NULL DEFAULT 0) ON COMMIT DELETE ROWS;
CREATE INDEX IF NOT EXISTS belief_in_key ON belief_in (self_key, holder_id);
CREATE TEMP TABLE IF NOT EXISTS belief_todo (holder_id text, hkey bigint, self_key bigint, follow_id bigint, action text, value_text text, value_num float8, confidence float8, observability float8, previous_text text, pconf float8, split_ns bigint) ON COMMIT DELETE ROWS;
CREATE TEMP TABLE IF NOT EXISTS belief_freeze (follow_id bigint PRIMARY KEY, hkey bigint, from_ns bigint, cut_ns bigint, value_text text, value_num float8, confidence float8, observability float8) ON COMMIT DELETE ROWS;
CREATE TEMP TABLE IF NOT EXISTS belief_mat (follow_id bigint PRIMARY KEY) ON COMMIT DELETE ROWS;
-- The statements' join order is the written one (as SQLite's CROSS JOIN pins it), each planned
-- with the tick's values.
SET LOCAL join_collapse_limit = 1;
SET LOCAL plan_cache_mode = force_custom_plan
{{/postgresql}}
