-- Who perceives which entity at :t, for :phase 'around' (before or after the tick), 'before' or
-- 'after'. :everything = 1 computes it for every located entity, else for belief_focus only.
{{#sqlite}}
-- SQLite first keeps the self's perception facts (sf, below) in a scratch table: it resolves a
-- CTE again at each reference (sf's ~70, each reading the settings), which made this statement
-- most of the compilation of a connection's first run (docs/beliefs.md).
INSERT INTO belief_percepts (subject_id, property, target_id, confidence)
WITH
{{perception_settings}}
{{/sqlite}}
{{#postgresql}}
INSERT INTO belief_seen (holder_id, entity_id, phase, pconf)
WITH RECURSIVE
{{perception_settings}},
-- The self's perception facts holding at :t for the phase. PostgreSQL reads them through a
-- LATERAL subquery: one index range per perception key, whatever the history (the plan
-- differs; the rows are the same as SQLite's join).
sf(s, p, tg, c) AS ({{/postgresql}}
  SELECT k.subject_id, k.property, k.target_id, f.confidence
  FROM fact_keys k
{{#sqlite}}
  JOIN facts f ON f.key_id = k.id
{{/sqlite}}
{{#postgresql}}
  CROSS JOIN LATERAL (SELECT f.confidence FROM facts f WHERE f.key_id = k.id
{{/postgresql}}
    AND f.value_text NOT IN ('false', 'False', 'FALSE', '0')
    AND f.valid_from_ns <= :t
    AND CASE {{as_text(:phase)}} WHEN 'after' THEN f.valid_to_ns IS NULL
                    WHEN 'before' THEN f.valid_from_ns < :t AND (f.valid_to_ns IS NULL OR f.valid_to_ns >= :t)
                    ELSE f.valid_to_ns IS NULL OR f.valid_to_ns >= :t END
{{#postgresql}}
  ) AS f
{{/postgresql}}
  WHERE k.agent_id = :self
    AND (k.property IN (SELECT p FROM cfg_room) OR k.property IN (SELECT p FROM cfg_in)
         OR k.property IN (SELECT p FROM cfg_vis) OR k.property IN (SELECT a FROM cfg_att)){{#sqlite}};
INSERT INTO belief_seen (holder_id, entity_id, phase, pconf)
WITH RECURSIVE
{{perception_settings}},
sf(s, p, tg, c) AS (SELECT subject_id, property, target_id, confidence FROM belief_percepts
{{/sqlite}}
),
-- The holders whose perception is computed: not the members of a group (96_regroup), who
-- perceive as its representative does.
chain(holder, pos, member) AS (
  SELECT a.id, 1, a.id FROM agents a WHERE NOT a.is_self AND {{not_member(a.id)}}
  UNION ALL
  SELECT c.holder_id, c.position, c.member_id FROM belief_chain c
  WHERE c.holder_id IN (SELECT id FROM holders WHERE depth BETWEEN 2 AND (SELECT d FROM cfg_depth))
    AND {{not_member(c.holder_id)}}
),
chain_len(holder, n) AS (SELECT holder, MAX(pos) FROM chain GROUP BY holder),
members(m) AS (SELECT DISTINCT member FROM chain),
focus(e) AS (
  SELECT entity_id FROM belief_focus WHERE :everything = 0
  UNION SELECT s FROM sf WHERE :everything = 1
  UNION SELECT tg FROM sf WHERE :everything = 1 AND tg <> ''
  UNION SELECT m FROM members
),
up(e, cur) AS (
  SELECT e, e FROM focus
  UNION SELECT up.e, sf.tg FROM up JOIN sf ON sf.s = up.cur AND sf.p IN (SELECT p FROM cfg_in)
),
loc(e, room, c, p) AS (
  SELECT up.e, sf.tg, sf.c, sf.p FROM up JOIN sf ON sf.s = up.cur AND sf.p IN (SELECT p FROM cfg_room)
),
mp(m, e, c) AS (
  SELECT lm.e, le.e, lm.c FROM loc lm JOIN members ON members.m = lm.e JOIN loc le ON le.room = lm.room
  WHERE lm.p NOT IN (SELECT p FROM cfg_att)
  UNION ALL
  -- (the gated copresence properties, checked per pair only when attention is configured)
  SELECT lm.e, le.e, lm.c FROM loc lm JOIN members ON members.m = lm.e JOIN loc le ON le.room = lm.room
  WHERE lm.p IN (SELECT p FROM cfg_att)
    AND (lm.e = le.e OR EXISTS (SELECT 1 FROM sf a WHERE a.s = lm.e AND a.tg IN (le.e, lm.room, '')
                                  AND a.p IN (SELECT g.a FROM cfg_att g WHERE g.p = lm.p)))
  UNION ALL
  -- The actor of a change perceives it wherever it is.
  SELECT b.actor_id, k.subject_id, 1.0 FROM belief_changed b JOIN fact_keys k ON k.id = b.key_id
  WHERE b.actor_id IS NOT NULL
  UNION ALL
  SELECT b.actor_id, k.target_id, 1.0 FROM belief_changed b JOIN fact_keys k ON k.id = b.key_id
  WHERE b.actor_id IS NOT NULL AND k.target_id <> ''
  UNION ALL
  SELECT CASE v.side WHEN 'subject' THEN sf.s ELSE sf.tg END,
         CASE v.side WHEN 'subject' THEN sf.tg ELSE sf.s END, sf.c
  FROM sf JOIN cfg_vis v ON v.p = sf.p
  UNION ALL
  SELECT m, m, 1.0 FROM members
  WHERE {{setting(self_perception)}} = 'true'
),
mpm(m, e, c) AS (
  SELECT m, e, MAX(c) FROM mp WHERE m IN (SELECT m FROM members) GROUP BY m, e
),
-- Nested holders (chains of 2 or more) only: first-order holders are read from mp directly.
cp(holder, pos, e, c) AS (
  SELECT ch.holder, 1, x.e, x.c FROM chain ch
  JOIN chain_len n ON n.holder = ch.holder AND n.n >= 2
  JOIN mpm x ON x.m = ch.member WHERE ch.pos = 1
  UNION ALL
  SELECT cp.holder, ch.pos, x.e, cp.c * x.c
  FROM cp
  JOIN chain ch ON ch.holder = cp.holder AND ch.pos = cp.pos + 1
  JOIN chain prev ON prev.holder = cp.holder AND prev.pos = cp.pos
  JOIN mpm link ON link.m = prev.member AND link.e = ch.member
  JOIN mpm x ON x.m = ch.member AND x.e = cp.e
)
SELECT ch.holder, mp.e, {{as_text(:phase)}}, MAX(mp.c)
FROM chain ch JOIN chain_len n ON n.holder = ch.holder AND n.n = 1
JOIN mp ON mp.m = ch.member
WHERE mp.e IN (SELECT e FROM focus)
GROUP BY ch.holder, mp.e
UNION ALL
SELECT cp.holder, cp.e, {{as_text(:phase)}}, MAX(cp.c)
FROM cp JOIN chain_len n ON n.holder = cp.holder AND n.n = cp.pos
WHERE cp.e IN (SELECT e FROM focus)
GROUP BY cp.holder, cp.e
{{#sqlite}};
DELETE FROM belief_percepts
{{/sqlite}}
{{#postgresql}};
-- Temporary tables get no statistics unless asked: without them the planner probed the
-- index by entity alone in 35_freeze and filtered every holder (docs/beliefs.md).
ANALYZE belief_seen
{{/postgresql}}
