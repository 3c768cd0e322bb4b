-- Register the nested holders A>B (and deeper, up to the depth setting) of the first-order
-- agents (every agent that is not self) that are missing: a holders row (no entity, no agent,
-- no per-agent views: those are for real agents) and its chain in belief_chain. The new ones
-- stay in belief_new_chain until holders_seen (the reperceive block runs when there are any).
-- holders_basis remembers the agents and depth this was done for. A new holder whose agents the
-- robot's facts name (one this run may write: pipeline.MINE) is at the run's time on the rules'
-- clock (pipeline.CLOCK), so that no later run writes its rows before this one's; the others
-- (pairs of people this robot never saw) have no clock yet.
UPDATE store_state SET holders_basis = {{holders_basis}} WHERE id = 1;
INSERT INTO belief_new_chain (holder_id, position, member_id)
WITH RECURSIVE
first_order(id) AS (
  SELECT id FROM agents WHERE NOT is_self
),
chain(holder_id, last_id, n) AS (
  SELECT id, id, 1 FROM first_order
  UNION ALL
  SELECT c.holder_id || '>' || f.id, f.id, c.n + 1
  FROM chain c JOIN first_order f ON f.id <> c.last_id
  WHERE c.n < CAST({{setting(depth)}} AS INTEGER)
)
SELECT h.holder_id, p.n, p.last_id
FROM chain h JOIN chain p ON p.n <= h.n
  AND (p.holder_id = h.holder_id
       OR substr(h.holder_id, 1, length(p.holder_id) + 1) = p.holder_id || '>')
WHERE h.n >= 2 AND h.holder_id NOT IN (SELECT id FROM holders);
INSERT INTO holders (id, agent_id, depth, registered_ns)
SELECT holder_id, NULL, MAX(position), :t FROM belief_new_chain GROUP BY holder_id;
UPDATE holders SET clock_ns = :t, clock_self = :self
WHERE id IN (SELECT holder_id FROM belief_new_chain) AND NOT EXISTS (
  SELECT 1 FROM belief_new_chain c WHERE c.holder_id = holders.id
    AND NOT EXISTS (SELECT 1 FROM fact_keys k WHERE k.subject_id = c.member_id AND k.agent_id = :self)
    AND NOT EXISTS (SELECT 1 FROM fact_keys k WHERE k.target_id = c.member_id AND k.agent_id = :self));
INSERT INTO belief_chain (holder_id, position, member_id)
SELECT holder_id, position, member_id FROM belief_new_chain
