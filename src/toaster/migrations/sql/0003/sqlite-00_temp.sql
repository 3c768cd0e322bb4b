-- Per-connection scratch tables of one rule run (emptied by 99_clear).
-- belief_changed: the self keys written by the tick; for a refreshed key (same value, new
-- number / confidence / observability, updated in place) the values it had before the tick.
CREATE TEMP TABLE IF NOT EXISTS belief_changed (key_id INTEGER PRIMARY KEY, refreshed INTEGER NOT NULL, prev_num REAL, prev_conf REAL, prev_obs REAL);
CREATE TEMP TABLE IF NOT EXISTS belief_focus (entity_id TEXT PRIMARY KEY);
CREATE TEMP TABLE IF NOT EXISTS belief_seen (holder_id TEXT, entity_id TEXT, phase TEXT, pconf REAL);
CREATE INDEX IF NOT EXISTS temp.belief_seen_entity_holder ON belief_seen (entity_id, phase, holder_id);
CREATE TEMP TABLE IF NOT EXISTS belief_in (holder_id TEXT, self_key INTEGER, hkey INTEGER, pconf REAL, seen_again INTEGER NOT NULL DEFAULT 0);
CREATE INDEX IF NOT EXISTS temp.belief_in_key ON belief_in (self_key, holder_id);
CREATE TEMP TABLE IF NOT EXISTS belief_todo (holder_id TEXT, hkey INTEGER, self_key INTEGER, follow_id INTEGER, action TEXT, value_text TEXT, value_num REAL, confidence REAL, observability REAL, previous_text TEXT, pconf REAL, split_ns INTEGER);
CREATE TEMP TABLE IF NOT EXISTS belief_freeze (follow_id INTEGER PRIMARY KEY, hkey INTEGER, from_ns INTEGER, cut_ns INTEGER, value_text TEXT, value_num REAL, confidence REAL, observability REAL);
CREATE TEMP TABLE IF NOT EXISTS belief_mat (follow_id INTEGER PRIMARY KEY)
