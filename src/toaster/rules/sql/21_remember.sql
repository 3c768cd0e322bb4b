-- Keep who perceives what after this run (20_perceive's 'after' rows, every located entity):
-- the next runs whose changes hold no perception input reuse it (20_reuse) instead of
-- computing it. It holds from :t when no perception fact of the self agent starts or ends at
-- :t (then perceiving 'around' :t is perceiving after it), else from :t + 1; the pipeline
-- keeps nothing when one starts or ends later (pipeline.REMEMBER). The settled keys were
-- settled for the perception before: they are forgotten.
DELETE FROM belief_settled;
DELETE FROM belief_perceived;
INSERT INTO belief_perceived (entity_id, holder_id, pconf)
SELECT entity_id, holder_id, pconf FROM belief_seen WHERE phase = 'after';
UPDATE store_state SET perceived_for = :self,
  perceived_ns = CASE WHEN COALESCE({{perception_horizon(:self)}}, :t - 1) < :t THEN :t
                      ELSE :t + 1 END
WHERE id = 1
