-- The agents and depth the nested holders are now registered for.
UPDATE store_state SET holders_basis = {{holders_basis}} WHERE id = 1
