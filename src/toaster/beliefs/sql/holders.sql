-- Register the nested holders A>B (and deeper, up to the depth setting) of the first-order
-- agents (every agent that is neither self nor nested) that are missing: their chains in
-- belief_chain, an entity of kind 'belief' and an agent row each (no per-agent views: those are
-- for real agents). holders_basis remembers the agents and depth this was done for.
UPDATE store_state SET holders_basis = {{holders_basis}} WHERE id = 1;
INSERT INTO belief_new_chain (holder_id, position, member_id)
WITH RECURSIVE
first_order(id) AS (
  SELECT id FROM agents WHERE NOT is_self AND id NOT IN (SELECT holder_id FROM belief_chain)
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
WHERE h.n >= 2 AND h.holder_id NOT IN (SELECT holder_id FROM belief_chain)
  AND h.holder_id NOT IN (SELECT id FROM first_order);
{{insert_or_ignore}} INTO entities (id, name, kind, owner_id, created_ns)
SELECT DISTINCT holder_id, holder_id, 'belief', '', :t FROM belief_new_chain
WHERE holder_id IS NOT NULL {{on_conflict_ignore}};
INSERT INTO agents (id, num, is_self, registered_ns)
SELECT holder_id, (SELECT COALESCE(MAX(num), 0) FROM agents)
                  + ROW_NUMBER() OVER (ORDER BY holder_id), 1 = 0, :t
FROM (SELECT DISTINCT holder_id FROM belief_new_chain) h
WHERE holder_id NOT IN (SELECT id FROM agents);
INSERT INTO belief_chain (holder_id, position, member_id)
SELECT holder_id, position, member_id FROM belief_new_chain;
DELETE FROM belief_new_chain
