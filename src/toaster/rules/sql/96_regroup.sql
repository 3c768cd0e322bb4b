-- Holders that perceive alike share the rule's work: a group is a representative (the first
-- holder of its kind) and the holders that perceive exactly as it does and follow exactly the
-- same self keys with the same confidence. Perceiving alike, as 20_perceive computes it: every
-- agent of the holder's chain is in the same single room, with confidence 1, its co-presence
-- not gated by attention (setting attention) and no visibility fact of its own. Such holders
-- see everything in that room and nothing else, so while no perception fact changes
-- (pipeline.STEADY) the representative's perception and decisions are the members' (20_perceive
-- skips the members, 32_expand and 35_freeze give them the representative's changes).
-- Settings with group_holders = false keep no groups.
{{#sqlite}}
-- SQLite first keeps the self's open perception facts (sf) in a scratch table, as 20_perceive.
INSERT INTO belief_percepts (subject_id, property, target_id, confidence)
WITH
{{perception_settings}}
{{/sqlite}}
{{#postgresql}}
INSERT INTO belief_groups (holder_id, rep_id)
WITH RECURSIVE
cfg_room(p) AS (SELECT value FROM {{setting_list(copresence)}}),
cfg_in(p) AS (SELECT value FROM {{setting_list(containment)}}),
cfg_vis(p, side) AS (SELECT key, value FROM {{setting_map(visibility)}}),
cfg_att(p) AS (SELECT x.key FROM {{setting_pairs(attention)}} AS x),
cfg_depth(d) AS (SELECT CAST({{setting(depth)}} AS INTEGER)),
sf(s, p, tg, c) AS ({{/postgresql}}
  SELECT k.subject_id, k.property, k.target_id, f.confidence
  FROM fact_keys k JOIN facts f {{open_fact}} ON f.key_id = k.id AND f.valid_to_ns IS NULL
  WHERE k.agent_id = :self AND f.value_text NOT IN ('false', 'False', 'FALSE', '0')
    AND (k.property IN (SELECT p FROM cfg_room) OR k.property IN (SELECT p FROM cfg_in)
         OR k.property IN (SELECT p FROM cfg_vis)){{#sqlite}};
INSERT INTO belief_groups (holder_id, rep_id)
WITH RECURSIVE
{{perception_settings}},
sf(s, p, tg, c) AS (SELECT subject_id, property, target_id, confidence FROM belief_percepts
{{/sqlite}}
),
members(m) AS (SELECT id FROM agents WHERE NOT is_self),
up(e, cur) AS (
  SELECT m, m FROM members
  UNION SELECT up.e, sf.tg FROM up JOIN sf ON sf.s = up.cur AND sf.p IN (SELECT p FROM cfg_in)
),
loc(e, room, c, p) AS (
  SELECT up.e, sf.tg, sf.c, sf.p FROM up JOIN sf ON sf.s = up.cur AND sf.p IN (SELECT p FROM cfg_room)
),
seeing(m) AS (
  SELECT CASE v.side WHEN 'subject' THEN sf.s ELSE sf.tg END FROM sf JOIN cfg_vis v ON v.p = sf.p
),
plain(m, room) AS (
  SELECT e, MIN(room) FROM loc
  WHERE e NOT IN (SELECT m FROM seeing WHERE m IS NOT NULL)
  GROUP BY e
  HAVING COUNT(*) = 1 AND MIN(c) >= 1.0
     AND SUM(CASE WHEN p IN (SELECT p FROM cfg_att) THEN 1 ELSE 0 END) = 0
),
chain(holder, member) AS (
  SELECT m, m FROM members
  UNION ALL
  SELECT c.holder_id, c.member_id FROM belief_chain c
  WHERE c.holder_id IN (SELECT id FROM holders WHERE depth BETWEEN 2 AND (SELECT d FROM cfg_depth))
),
kind(holder, room) AS (
  SELECT ch.holder, MIN(p.room) FROM chain ch LEFT JOIN plain p ON p.m = ch.member
  GROUP BY ch.holder
  HAVING COUNT(p.m) = COUNT(*) AND MIN(p.room) = MAX(p.room)
),
first_of(room, holder) AS (SELECT room, MIN(holder) FROM kind GROUP BY room HAVING COUNT(*) >= 2),
followed(holder, n) AS (
  SELECT k.agent_id, COUNT(*) FROM fact_keys k
  JOIN belief_follow w {{open_follow}} ON w.hkey = k.id AND w.to_ns IS NULL
  WHERE k.agent_id IN (SELECT holder FROM kind)
  GROUP BY k.agent_id
),
alike(holder, rep) AS (
  SELECT h.holder, r.holder FROM kind h JOIN first_of r ON r.room = h.room
  WHERE COALESCE((SELECT n FROM followed WHERE followed.holder = h.holder), 0)
      = COALESCE((SELECT n FROM followed WHERE followed.holder = r.holder), 0)
    AND NOT EXISTS (
      SELECT 1 FROM fact_keys hk JOIN belief_follow w {{open_follow}} ON w.hkey = hk.id
        AND w.to_ns IS NULL
      WHERE hk.agent_id = h.holder AND h.holder <> r.holder
        AND NOT EXISTS (SELECT 1 FROM belief_follow x WHERE x.self_key = w.self_key
                          AND x.holder_id = r.holder AND x.to_ns IS NULL AND x.pconf = w.pconf))
)
SELECT holder, rep FROM alike
WHERE {{setting(group_holders)}} = 'true'
  AND rep IN (SELECT rep FROM alike WHERE holder <> rep);
{{#sqlite}}
DELETE FROM belief_percepts;
{{/sqlite}}
UPDATE store_state SET groups_for = :self WHERE id = 1
