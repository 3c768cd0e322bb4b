-- Grouped holders (96_regroup): a group's members take what its representative takes, since
-- they perceive alike and follow the same keys; the write steps then run per holder.
INSERT INTO belief_in (holder_id, self_key, hkey, pconf)
SELECT g.holder_id, i.self_key, NULL, i.pconf
FROM belief_in i {{pinned_join}} belief_groups g ON g.rep_id = i.holder_id
WHERE g.holder_id <> g.rep_id
