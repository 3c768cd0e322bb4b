-- TRUNCATE, not DELETE: temporary tables are never vacuumed, and the dead rows of every tick
-- would pile up in them and in their index (ticks got slower and slower).
TRUNCATE belief_changed, belief_focus, belief_seen, belief_in, belief_todo, belief_freeze
