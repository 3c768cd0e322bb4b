-- The kept perception (21_remember) as this run's: who perceives each entity of the focus,
-- for the computed holders (not the members of a group), phase 'around'. It is what
-- 20_perceive computes at :t: no perception fact changed since it was kept (pipeline.REUSE).
DELETE FROM belief_seen;
INSERT INTO belief_seen (holder_id, entity_id, phase, pconf)
SELECT p.holder_id, p.entity_id, 'around', p.pconf
FROM belief_focus f {{pinned_join}} belief_perceived p ON p.entity_id = f.entity_id
WHERE {{not_member(p.holder_id)}}
{{#postgresql}};
-- (statistics, as after 20_perceive: docs/beliefs.md)
ANALYZE belief_seen
{{/postgresql}}
