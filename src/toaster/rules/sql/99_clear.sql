-- Empty the scratch tables for the next tick (belief_mat is emptied by 95_materialize).
DELETE FROM belief_changed;
DELETE FROM belief_focus;
DELETE FROM belief_seen;
DELETE FROM belief_in;
DELETE FROM belief_todo;
DELETE FROM belief_freeze
