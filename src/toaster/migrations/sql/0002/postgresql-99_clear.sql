DELETE FROM belief_keys;
DELETE FROM belief_focus;
DELETE FROM belief_seen;
DELETE FROM belief_in;
DELETE FROM belief_plan
