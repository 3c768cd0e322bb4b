CREATE TEMP TABLE IF NOT EXISTS belief_keys (key_id INTEGER PRIMARY KEY);
CREATE TEMP TABLE IF NOT EXISTS belief_focus (entity_id TEXT PRIMARY KEY);
CREATE TEMP TABLE IF NOT EXISTS belief_seen (holder_id TEXT, entity_id TEXT, phase TEXT, pconf REAL);
CREATE INDEX IF NOT EXISTS temp.belief_seen_entity ON belief_seen (entity_id, phase);
CREATE TEMP TABLE IF NOT EXISTS belief_in (holder_id TEXT, self_key INTEGER, hkey INTEGER, pconf REAL);
CREATE TEMP TABLE IF NOT EXISTS belief_plan (holder_id TEXT, hkey INTEGER, action TEXT, value_text TEXT, value_num REAL, confidence REAL, observability REAL, previous_text TEXT)
