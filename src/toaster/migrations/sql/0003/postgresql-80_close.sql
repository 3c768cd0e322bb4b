UPDATE facts SET valid_to_ns = :t
WHERE valid_to_ns IS NULL
  AND key_id IN (SELECT hkey FROM belief_todo WHERE action IN ('changed', 'ended'))
