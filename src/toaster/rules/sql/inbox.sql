-- fact_inbox: the write surface of plain SQL clients. One inserted row is one write, applied by
-- the database as toaster's store applies it (Store.assert_fact with unknown entities
-- registered, retract_facts, record_event), in the writer's transaction; a write to a self
-- agent then runs the belief rule (belief_runs). The row itself is never kept.
-- NEW: the inbox row (action, agent_id, subject_id, subject_owner_id, property, property_type,
-- sub_property, target_id, target_owner_id, value_text, value_num, confidence, observability,
-- t_ns, source). For assert and event, NULL key fields mean ''; for retract, NULL (or 'NULL'
-- for subject and target, the original's wildcard) matches any.
{{#sqlite}}
SELECT RAISE(ABORT, 'fact_inbox: action must be assert, retract or event')
WHERE NEW.action NOT IN ('assert', 'retract', 'event');
SELECT RAISE(ABORT, 'fact_inbox: agent_id is not a registered agent or belief holder: register the agent first (toaster set-info ENTITY --id ID --type human|robot)')
WHERE NOT EXISTS (SELECT 1 FROM holders WHERE id = NEW.agent_id);
SELECT RAISE(ABORT, 'fact_inbox: actor_id is not a registered agent: name the agent who made the change, or leave it NULL')
WHERE NEW.actor_id IS NOT NULL AND NOT EXISTS (SELECT 1 FROM agents WHERE id = NEW.actor_id);
SELECT RAISE(ABORT, 'fact_inbox: give property, and subject_id unless you retract (NULL subject_id retracts any)')
WHERE COALESCE(NEW.property, '') = '' OR (NEW.action <> 'retract' AND COALESCE(NEW.subject_id, '') = '');
SELECT RAISE(ABORT, 'fact_inbox: give t_ns, the time of the write in integer nanoseconds')
WHERE NEW.t_ns IS NULL OR typeof(NEW.t_ns) <> 'integer';
SELECT RAISE(ABORT, 'fact_inbox: confidence and observability must be between 0 and 1')
WHERE NOT (NEW.confidence BETWEEN 0 AND 1 AND NEW.observability BETWEEN 0 AND 1);
SELECT RAISE(ABORT, 'fact_inbox: a fact to retract started after t_ns: retract it at or after its start')
WHERE NEW.action = 'retract' AND EXISTS (SELECT 1 FROM {{inbox_match}} AND f.valid_from_ns > NEW.t_ns);
SELECT RAISE(ABORT, 'fact_inbox: the fact already changed after t_ns (its last interval starts or ends later): write each fact in time order')
WHERE NEW.action = 'assert' AND {{inbox_later}};
{{/sqlite}}
{{#postgresql}}
IF NEW.action IS NULL OR NEW.action NOT IN ('assert', 'retract', 'event') THEN
  RAISE EXCEPTION 'fact_inbox: action %L must be assert, retract or event', NEW.action;
END IF;
IF NOT EXISTS (SELECT 1 FROM holders WHERE id = NEW.agent_id) THEN
  RAISE EXCEPTION 'fact_inbox: agent_id %L is not a registered agent or belief holder: register the agent first (toaster set-info ENTITY --id ID --type human|robot)', NEW.agent_id;
END IF;
IF NEW.actor_id IS NOT NULL AND NOT EXISTS (SELECT 1 FROM agents WHERE id = NEW.actor_id) THEN
  RAISE EXCEPTION 'fact_inbox: actor_id %L is not a registered agent: name the agent who made the change, or leave it NULL', NEW.actor_id;
END IF;
IF COALESCE(NEW.property, '') = '' OR (NEW.action <> 'retract' AND COALESCE(NEW.subject_id, '') = '') THEN
  RAISE EXCEPTION 'fact_inbox: give property, and subject_id unless you retract (NULL subject_id retracts any)';
END IF;
IF NEW.t_ns IS NULL THEN
  RAISE EXCEPTION 'fact_inbox: give t_ns, the time of the write in integer nanoseconds';
END IF;
IF NOT (NEW.confidence BETWEEN 0 AND 1 AND NEW.observability BETWEEN 0 AND 1) THEN
  RAISE EXCEPTION 'fact_inbox: confidence % and observability % must be between 0 and 1', NEW.confidence, NEW.observability;
END IF;
IF NEW.action = 'retract' AND EXISTS (SELECT 1 FROM {{inbox_match}} AND f.valid_from_ns > NEW.t_ns) THEN
  RAISE EXCEPTION 'fact_inbox: a % fact to retract started after t_ns %: retract it at or after its start', NEW.property, NEW.t_ns;
END IF;
IF NEW.action = 'assert' AND {{inbox_later}} THEN
  RAISE EXCEPTION 'fact_inbox: the % fact already changed after t_ns % (its last interval starts or ends later): write each fact in time order', NEW.property, NEW.t_ns;
END IF;
{{/postgresql}}
-- Ids a write stores are checked as the library checks them (model.check_id).
{{inbox_id_checks}}
-- A write to an agent that is not self first turns the rows it shares with the self into its
-- own (Store._resolve / retract_facts detach): 95_materialize over these periods.
INSERT INTO belief_mat (follow_id)
SELECT w.id FROM fact_keys k JOIN belief_follow w ON w.hkey = k.id AND w.to_ns IS NULL
WHERE k.agent_id = NEW.agent_id AND NEW.action <> 'event' AND NOT {{inbox_self}}
UNION
SELECT w.id FROM fact_keys k JOIN belief_follow w ON w.self_key = k.id
WHERE k.agent_id = NEW.agent_id AND NEW.action <> 'event' AND NOT {{inbox_self}};
{{materialize}};
-- Entities a fact names register as kind '' (as a snapshot's do).
{{insert_or_ignore}} INTO entities (id, name, kind, owner_id, created_ns)
SELECT e.id, e.id, '', e.owner_id, NEW.t_ns
FROM (SELECT NEW.subject_id AS id, COALESCE(NEW.subject_owner_id, '') AS owner_id
      UNION ALL SELECT NEW.target_id, COALESCE(NEW.target_owner_id, '')) e
WHERE NEW.action <> 'retract' AND COALESCE(e.id, '') <> '' {{on_conflict_ignore}};
{{insert_or_ignore}} INTO fact_keys (agent_id, subject_id, subject_owner_id, property,
                                     sub_property, target_id, target_owner_id, property_type)
SELECT NEW.agent_id, NEW.subject_id, COALESCE(NEW.subject_owner_id, ''), NEW.property,
       COALESCE(NEW.sub_property, ''), COALESCE(NEW.target_id, ''),
       COALESCE(NEW.target_owner_id, ''), COALESCE(NEW.property_type, '')
WHERE NEW.action <> 'retract' {{on_conflict_ignore}};
-- The self keys this write changes, as the rule reads them: a refreshed key (same value, new
-- numbers) with the numbers it held.
INSERT INTO belief_changed (key_id, refreshed, prev_num, prev_conf, prev_obs, actor_id)
SELECT k.id, f.id IS NOT NULL AND f.value_text = NEW.value_text,
       CASE WHEN f.value_text = NEW.value_text THEN f.value_num END,
       CASE WHEN f.value_text = NEW.value_text THEN f.confidence END,
       CASE WHEN f.value_text = NEW.value_text THEN f.observability END, NEW.actor_id
FROM fact_keys k LEFT JOIN facts f ON f.key_id = k.id AND f.valid_to_ns IS NULL
WHERE k.id = {{inbox_key}} AND NEW.action = 'assert' AND {{inbox_self}}
  AND (f.id IS NULL OR f.value_text <> NEW.value_text OR {{inbox_renumbered}});
INSERT INTO belief_changed (key_id, refreshed, prev_num, prev_conf, prev_obs, actor_id)
SELECT k.id, 1 = 0, NULL, NULL, NULL, NEW.actor_id FROM {{inbox_match}}
  AND NEW.action = 'retract' AND {{inbox_self}};
-- assert: retype, refresh (the numbers held kept as a sample until t), change, appear.
UPDATE fact_keys SET property_type = COALESCE(NEW.property_type, '')
WHERE id = {{inbox_key}} AND NEW.action = 'assert'
  AND property_type <> COALESCE(NEW.property_type, '')
  AND EXISTS (SELECT 1 FROM facts f WHERE f.key_id = fact_keys.id AND f.valid_to_ns IS NULL);
INSERT INTO fact_samples (fact_id, until_ns, value_num, confidence, observability)
SELECT f.id, NEW.t_ns, f.value_num, f.confidence, f.observability
FROM facts f {{open_fact}}
WHERE f.key_id = {{inbox_key}} AND f.valid_to_ns IS NULL AND NEW.action = 'assert'
  AND f.value_text = NEW.value_text AND {{inbox_renumbered}}
ON CONFLICT DO NOTHING;
UPDATE facts SET value_num = NEW.value_num, confidence = NEW.confidence,
                 observability = NEW.observability
WHERE {{inbox_open_interval}} AND NEW.action = 'assert'
  AND value_text = NEW.value_text
  AND (value_num {{is_distinct}} NEW.value_num OR confidence <> NEW.confidence
       OR observability <> NEW.observability);
INSERT INTO events (key_id, agent_id, kind, stamp_ns, value_text, value_num, confidence,
                    observability, previous_text, source, recorded_ns)
SELECT k.id, NEW.agent_id, CASE WHEN f.id IS NULL THEN 'appeared' ELSE 'changed' END, NEW.t_ns,
       NEW.value_text, NEW.value_num, NEW.confidence, NEW.observability, f.value_text,
       NEW.source, {{now_ns}}
FROM fact_keys k LEFT JOIN facts f ON f.key_id = k.id AND f.valid_to_ns IS NULL
WHERE k.id = {{inbox_key}} AND NEW.action = 'assert'
  AND (f.id IS NULL OR f.value_text <> NEW.value_text);
UPDATE facts SET valid_to_ns = NEW.t_ns
WHERE {{inbox_open_interval}} AND NEW.action = 'assert' AND value_text <> NEW.value_text;
INSERT INTO facts (key_id, value_text, value_num, confidence, observability, valid_from_ns,
                   recorded_ns, source)
SELECT {{inbox_key}}, NEW.value_text, NEW.value_num, NEW.confidence, NEW.observability,
       NEW.t_ns, {{now_ns}}, NEW.source
WHERE NEW.action = 'assert'
  AND NOT EXISTS (SELECT 1 FROM facts f WHERE f.key_id = {{inbox_key}} AND f.valid_to_ns IS NULL);
-- retract: the matching current facts end at t.
INSERT INTO events (key_id, agent_id, kind, stamp_ns, value_text, value_num, confidence,
                    observability, previous_text, source, recorded_ns)
SELECT k.id, NEW.agent_id, 'ended', NEW.t_ns, f.value_text, f.value_num, f.confidence,
       f.observability, NULL, NEW.source, {{now_ns}}
FROM {{inbox_match}} AND NEW.action = 'retract'
ORDER BY k.id;
UPDATE facts SET valid_to_ns = NEW.t_ns
WHERE valid_to_ns IS NULL AND NEW.action = 'retract'
  AND key_id IN (SELECT k.id FROM {{inbox_match}});
-- event: a point event (the original's set_info EVENT).
INSERT INTO events (key_id, agent_id, kind, stamp_ns, value_text, value_num, confidence,
                    observability, previous_text, source, recorded_ns)
SELECT {{inbox_key}}, NEW.agent_id, 'event', NEW.t_ns, NEW.value_text, NEW.value_num,
       NEW.confidence, NEW.observability, NULL, NEW.source, {{now_ns}}
WHERE NEW.action = 'event';
-- Other stores re-read what their sources hold (Store.bump_epoch).
UPDATE store_state SET cache_epoch = cache_epoch + 1 WHERE id = 1 AND NEW.action <> 'event';
-- The rule, for a self agent's changes.
INSERT INTO belief_runs (self_id, t_ns, recorded_ns)
SELECT NEW.agent_id, NEW.t_ns, {{now_ns}}
WHERE {{inbox_self}} AND EXISTS (SELECT 1 FROM belief_changed)
