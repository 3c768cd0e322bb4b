-- The groups of holders (96_regroup) no longer hold: a run that changes perception, or a write
-- that changes one holder's followed keys. The run ends by forming them again.
DELETE FROM belief_groups;
{{ungroup}}
