-- The nested holders are registered and perceive: the agents and depth they are registered
-- for, and nobody new any more.
UPDATE store_state SET holders_basis = {{holders_basis}} WHERE id = 1;
DELETE FROM belief_new_chain
