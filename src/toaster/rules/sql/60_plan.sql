-- What each holder key does. Not following: appeared or changed (event, close, then follow the
-- self key from :t), ended (event, close), refreshed (update in place). Following with another
-- perception confidence: repconf. The self interval that holds now takes the new confidence:
-- when it started at :t the period is split at :t (the event of :t too); when it started
-- inside the period or at its start, the period is split where it started (its event keeps
-- the old confidence, as an update in place would); when it started before, pconf is updated
-- in place.
INSERT INTO belief_todo (holder_id, hkey, self_key, follow_id, action, value_text, value_num,
                         confidence, observability, previous_text, pconf, split_ns)
SELECT holder_id, hkey, self_key, follow_id, action,
       CASE action WHEN 'ended' THEN h_text ELSE s_text END,
       CASE action WHEN 'ended' THEN h_num ELSE s_num END,
       CASE action WHEN 'ended' THEN h_conf ELSE new_conf END,
       CASE action WHEN 'ended' THEN h_obs ELSE s_obs END,
       CASE action WHEN 'changed' THEN h_text END,
       pconf,
       CASE WHEN action = 'repconf' AND s_from >= w_from THEN s_from END
FROM (
  SELECT g.holder_id, g.hkey, g.self_key, g.pconf, w.id AS follow_id, w.from_ns AS w_from,
         sf.valid_from_ns AS s_from,
         sf.value_text AS s_text, sf.value_num AS s_num,
         {{lo}}(1.0, sf.confidence * g.pconf) AS new_conf, sf.observability AS s_obs,
         hf.value_text AS h_text, hf.value_num AS h_num, hf.confidence AS h_conf,
         hf.observability AS h_obs,
         CASE
           WHEN w.id IS NOT NULL THEN CASE WHEN sf.key_id IS NOT NULL AND w.pconf <> g.pconf
                                           THEN 'repconf' END
           WHEN sf.key_id IS NULL THEN CASE WHEN hf.key_id IS NOT NULL THEN 'ended' END
           WHEN hf.key_id IS NULL THEN 'appeared'
           WHEN hf.value_text <> sf.value_text THEN 'changed'
           WHEN hf.value_num {{is_distinct}} sf.value_num OR hf.observability <> sf.observability
                OR hf.confidence <> {{lo}}(1.0, sf.confidence * g.pconf) THEN 'refreshed'
         END AS action
  FROM (SELECT holder_id, hkey, MAX(self_key) AS self_key, MAX(pconf) AS pconf
        FROM belief_in WHERE hkey IS NOT NULL GROUP BY holder_id, hkey) g
  LEFT JOIN belief_follow w {{open_follow}}
    ON w.hkey = g.hkey AND w.to_ns IS NULL
  LEFT JOIN facts sf {{open_fact}} ON sf.key_id = g.self_key AND sf.valid_to_ns IS NULL
  LEFT JOIN facts hf {{open_fact}} ON hf.key_id = g.hkey AND hf.valid_to_ns IS NULL
) AS planned WHERE action IS NOT NULL
