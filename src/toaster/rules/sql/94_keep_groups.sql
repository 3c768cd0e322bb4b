-- A group holds while its members follow the same keys: a member that took a change in place
-- (its own interval had the new value already: 'refreshed', not followed) while its
-- representative follows, or the reverse, ends the groups (96_regroup forms them again).
-- (With share_rows = false nobody follows: nothing to check.) The kept perception ends with
-- them (it covers the holders computed while they hold: 21_remember).
UPDATE store_state SET groups_for = NULL, perceived_for = NULL
WHERE id = 1 AND {{setting(share_rows)}} = 'true' AND EXISTS (
  SELECT 1 FROM belief_in i {{pinned_join}} belief_groups g ON g.holder_id = i.holder_id
  WHERE g.rep_id <> g.holder_id AND i.self_key IS NOT NULL
    AND CASE WHEN EXISTS (SELECT 1 FROM belief_follow w WHERE w.self_key = i.self_key
                            AND w.holder_id = g.rep_id AND w.to_ns IS NULL) THEN 1 ELSE 0 END
     <> CASE WHEN EXISTS (SELECT 1 FROM belief_follow w WHERE w.self_key = i.self_key
                            AND w.holder_id = i.holder_id AND w.to_ns IS NULL) THEN 1 ELSE 0 END);
DELETE FROM belief_groups WHERE {{groups_ended}}
