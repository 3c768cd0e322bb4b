-- New nested holders: forget who perceives what, to compute it again with them.
DELETE FROM belief_seen;
DELETE FROM belief_in
