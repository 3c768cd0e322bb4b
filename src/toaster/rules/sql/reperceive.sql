-- New nested holders: forget who perceives what, to compute it again with them (the kept
-- perception too: it has none of them).
UPDATE store_state SET perceived_for = NULL WHERE id = 1;
DELETE FROM belief_seen;
DELETE FROM belief_in
