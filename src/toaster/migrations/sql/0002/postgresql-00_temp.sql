CREATE TEMP TABLE IF NOT EXISTS belief_keys (key_id bigint PRIMARY KEY);
CREATE TEMP TABLE IF NOT EXISTS belief_focus (entity_id text PRIMARY KEY);
CREATE TEMP TABLE IF NOT EXISTS belief_seen (holder_id text, entity_id text, phase text, pconf float8);
CREATE INDEX IF NOT EXISTS belief_seen_entity ON belief_seen (entity_id, phase);
CREATE TEMP TABLE IF NOT EXISTS belief_in (holder_id text, self_key bigint, hkey bigint, pconf float8);
CREATE TEMP TABLE IF NOT EXISTS belief_plan (holder_id text, hkey bigint, action text, value_text text, value_num float8, confidence float8, observability float8, previous_text text);
-- The recursive perception query is written join by join in the order that keeps it small;
-- PostgreSQL's estimates on recursive CTEs are poor (rows=1 for thousands), and reordering
-- built millions of intermediate rows. Keep the written order for this transaction, and plan
-- each statement for its actual parameters (psycopg prepares statements after 5 runs, and
-- generic plans of these queries are far worse).
SET LOCAL join_collapse_limit = 1;
SET LOCAL plan_cache_mode = force_custom_plan
