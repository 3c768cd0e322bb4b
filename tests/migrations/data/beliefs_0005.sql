BEGIN TRANSACTION;
CREATE TABLE agents (
	id TEXT NOT NULL, 
	num INTEGER NOT NULL, 
	is_self BOOLEAN DEFAULT (false) NOT NULL, 
	registered_ns BIGINT NOT NULL, 
	CONSTRAINT pk_agents PRIMARY KEY (id), 
	CONSTRAINT fk_agents_id_entities FOREIGN KEY(id) REFERENCES entities (id) ON DELETE CASCADE, 
	CONSTRAINT uq_agents_num UNIQUE (num)
);
INSERT INTO "agents" VALUES('R',1,1,0);
INSERT INTO "agents" VALUES('ANNE',2,0,0);
INSERT INTO "agents" VALUES('BOB',3,0,0);
INSERT INTO "agents" VALUES('ANNE>BOB',4,0,10);
INSERT INTO "agents" VALUES('BOB>ANNE',5,0,10);
CREATE TABLE alembic_version (
	version_num VARCHAR(32) NOT NULL, 
	CONSTRAINT alembic_version_pkc PRIMARY KEY (version_num)
);
INSERT INTO "alembic_version" VALUES('0005');
CREATE TABLE areas (
	id TEXT NOT NULL, 
	owner_id TEXT DEFAULT ('') NOT NULL, 
	spec_json TEXT NOT NULL, 
	updated_ns BIGINT NOT NULL, 
	CONSTRAINT pk_areas PRIMARY KEY (id), 
	CONSTRAINT ck_areas_id_not_empty CHECK (id <> '')
);
CREATE TABLE belief_chain (
	holder_id TEXT NOT NULL, 
	position INTEGER NOT NULL, 
	member_id TEXT NOT NULL, 
	CONSTRAINT pk_belief_chain PRIMARY KEY (holder_id, position), 
	CONSTRAINT ck_belief_chain_position_positive CHECK (position >= 1), 
	CONSTRAINT fk_belief_chain_holder_id_agents FOREIGN KEY(holder_id) REFERENCES agents (id) ON DELETE CASCADE, 
	CONSTRAINT fk_belief_chain_member_id_agents FOREIGN KEY(member_id) REFERENCES agents (id) ON DELETE CASCADE
);
INSERT INTO "belief_chain" VALUES('ANNE>BOB',1,'ANNE');
INSERT INTO "belief_chain" VALUES('ANNE>BOB',2,'BOB');
INSERT INTO "belief_chain" VALUES('BOB>ANNE',1,'BOB');
INSERT INTO "belief_chain" VALUES('BOB>ANNE',2,'ANNE');
CREATE TABLE belief_follow (
	id INTEGER NOT NULL, 
	holder_id TEXT NOT NULL, 
	hkey BIGINT NOT NULL, 
	self_key BIGINT NOT NULL, 
	from_ns BIGINT NOT NULL, 
	to_ns BIGINT, 
	events_from_ns BIGINT NOT NULL, 
	events_to_ns BIGINT, 
	pconf FLOAT NOT NULL, 
	CONSTRAINT pk_belief_follow PRIMARY KEY (id), 
	CONSTRAINT ck_belief_follow_valid_period CHECK (to_ns IS NULL OR to_ns >= from_ns), 
	CONSTRAINT ck_belief_follow_pconf_positive CHECK (pconf >= 0)
);
INSERT INTO "belief_follow" VALUES(1,'ANNE',7,1,10,10,11,10,1.0);
INSERT INTO "belief_follow" VALUES(2,'ANNE',8,2,10,NULL,11,NULL,1.0);
INSERT INTO "belief_follow" VALUES(3,'ANNE',9,3,10,NULL,11,NULL,1.0);
INSERT INTO "belief_follow" VALUES(4,'ANNE',10,4,10,NULL,11,NULL,1.0);
INSERT INTO "belief_follow" VALUES(5,'ANNE',11,5,10,30,11,29,1.0);
INSERT INTO "belief_follow" VALUES(6,'ANNE',12,6,10,NULL,11,NULL,1.0);
INSERT INTO "belief_follow" VALUES(7,'ANNE>BOB',13,1,10,10,11,10,1.0);
INSERT INTO "belief_follow" VALUES(8,'ANNE>BOB',14,2,10,NULL,11,NULL,1.0);
INSERT INTO "belief_follow" VALUES(9,'ANNE>BOB',15,3,10,NULL,11,NULL,1.0);
INSERT INTO "belief_follow" VALUES(10,'ANNE>BOB',16,4,10,NULL,11,NULL,1.0);
INSERT INTO "belief_follow" VALUES(11,'ANNE>BOB',17,5,10,30,11,29,1.0);
INSERT INTO "belief_follow" VALUES(12,'ANNE>BOB',18,6,10,NULL,11,NULL,1.0);
INSERT INTO "belief_follow" VALUES(13,'BOB',19,1,10,10,11,10,1.0);
INSERT INTO "belief_follow" VALUES(14,'BOB',20,2,10,NULL,11,NULL,1.0);
INSERT INTO "belief_follow" VALUES(15,'BOB',21,3,10,NULL,11,NULL,1.0);
INSERT INTO "belief_follow" VALUES(16,'BOB',22,4,10,NULL,11,NULL,1.0);
INSERT INTO "belief_follow" VALUES(17,'BOB',23,5,10,30,11,30,1.0);
INSERT INTO "belief_follow" VALUES(18,'BOB',24,6,10,NULL,11,NULL,1.0);
INSERT INTO "belief_follow" VALUES(19,'BOB>ANNE',25,1,10,10,11,10,1.0);
INSERT INTO "belief_follow" VALUES(20,'BOB>ANNE',26,2,10,NULL,11,NULL,1.0);
INSERT INTO "belief_follow" VALUES(21,'BOB>ANNE',27,3,10,NULL,11,NULL,1.0);
INSERT INTO "belief_follow" VALUES(22,'BOB>ANNE',28,4,10,NULL,11,NULL,1.0);
INSERT INTO "belief_follow" VALUES(23,'BOB>ANNE',29,5,10,30,11,29,1.0);
INSERT INTO "belief_follow" VALUES(24,'BOB>ANNE',30,6,10,NULL,11,NULL,1.0);
INSERT INTO "belief_follow" VALUES(25,'ANNE',32,31,20,NULL,21,NULL,0.9);
INSERT INTO "belief_follow" VALUES(26,'ANNE>BOB',33,31,20,NULL,21,NULL,0.9);
INSERT INTO "belief_follow" VALUES(27,'BOB',34,31,20,NULL,21,NULL,1.0);
INSERT INTO "belief_follow" VALUES(28,'BOB>ANNE',35,31,20,NULL,21,NULL,0.9);
INSERT INTO "belief_follow" VALUES(29,'ANNE',7,1,10,10,11,10,0.9);
INSERT INTO "belief_follow" VALUES(30,'ANNE>BOB',13,1,10,10,11,10,0.9);
INSERT INTO "belief_follow" VALUES(31,'BOB>ANNE',25,1,10,10,11,10,0.9);
INSERT INTO "belief_follow" VALUES(32,'ANNE',37,36,30,NULL,31,NULL,0.9);
INSERT INTO "belief_follow" VALUES(33,'ANNE>BOB',38,36,30,NULL,31,NULL,0.9);
INSERT INTO "belief_follow" VALUES(34,'BOB',39,36,30,NULL,31,NULL,1.0);
INSERT INTO "belief_follow" VALUES(35,'BOB>ANNE',40,36,30,NULL,31,NULL,0.9);
INSERT INTO "belief_follow" VALUES(36,'ANNE',11,5,30,40,30,39,0.9);
INSERT INTO "belief_follow" VALUES(37,'ANNE>BOB',17,5,30,30,30,30,0.9);
INSERT INTO "belief_follow" VALUES(38,'BOB>ANNE',29,5,30,30,30,30,0.9);
INSERT INTO "belief_follow" VALUES(39,'ANNE',42,41,40,NULL,41,NULL,1.0);
INSERT INTO "belief_follow" VALUES(40,'ANNE',7,1,10,NULL,11,NULL,1.0);
INSERT INTO "belief_follow" VALUES(41,'ANNE',11,5,40,NULL,40,NULL,1.0);
CREATE TABLE belief_rules (
	backend TEXT NOT NULL, 
	step TEXT NOT NULL, 
	sql_text TEXT NOT NULL, 
	CONSTRAINT pk_belief_rules PRIMARY KEY (backend, step)
);
CREATE TABLE control_commands (
	id INTEGER NOT NULL, 
	kind TEXT NOT NULL, 
	args_json TEXT NOT NULL, 
	created_ns BIGINT NOT NULL, 
	state TEXT DEFAULT 'pending' NOT NULL, 
	answer_json TEXT, 
	done_ns BIGINT, 
	CONSTRAINT pk_control_commands PRIMARY KEY (id), 
	CONSTRAINT ck_control_commands_state_known CHECK (state IN ('pending', 'done', 'failed'))
);
CREATE TABLE entities (
	id TEXT NOT NULL, 
	name TEXT DEFAULT ('') NOT NULL, 
	kind TEXT DEFAULT ('') NOT NULL, 
	owner_id TEXT DEFAULT ('') NOT NULL, 
	created_ns BIGINT NOT NULL, 
	CONSTRAINT pk_entities PRIMARY KEY (id), 
	CONSTRAINT ck_entities_id_not_empty CHECK (id <> '')
);
INSERT INTO "entities" VALUES('R','R','robot','',0);
INSERT INTO "entities" VALUES('ANNE','ANNE','human','',0);
INSERT INTO "entities" VALUES('BOB','BOB','human','',0);
INSERT INTO "entities" VALUES('MUG','MUG','object','',0);
INSERT INTO "entities" VALUES('BOX','BOX','object','',0);
INSERT INTO "entities" VALUES('LAB','LAB','object','',0);
INSERT INTO "entities" VALUES('HALL','HALL','object','',0);
INSERT INTO "entities" VALUES('ANNE>BOB','ANNE>BOB','belief','',10);
INSERT INTO "entities" VALUES('BOB>ANNE','BOB>ANNE','belief','',10);
CREATE TABLE events (
	id INTEGER NOT NULL, 
	key_id BIGINT NOT NULL, 
	agent_id TEXT NOT NULL, 
	kind TEXT NOT NULL, 
	stamp_ns BIGINT NOT NULL, 
	value_text TEXT, 
	value_num FLOAT, 
	confidence FLOAT, 
	observability FLOAT, 
	previous_text TEXT, 
	source TEXT NOT NULL, 
	recorded_ns BIGINT NOT NULL, 
	CONSTRAINT pk_events PRIMARY KEY (id), 
	CONSTRAINT ck_events_kind_known CHECK (kind IN ('appeared', 'changed', 'ended', 'event'))
);
INSERT INTO "events" VALUES(1,1,'R','appeared',10,'true',NULL,1.0,1.0,NULL,'world',1795473399614446991);
INSERT INTO "events" VALUES(2,2,'R','appeared',10,'true',NULL,1.0,1.0,NULL,'world',1795473399614446991);
INSERT INTO "events" VALUES(3,3,'R','appeared',10,'true',NULL,1.0,1.0,NULL,'world',1795473399614446991);
INSERT INTO "events" VALUES(4,4,'R','appeared',10,'true',NULL,1.0,1.0,NULL,'world',1795473399614446991);
INSERT INTO "events" VALUES(5,5,'R','appeared',10,'red',NULL,1.0,1.0,NULL,'world',1795473399614446991);
INSERT INTO "events" VALUES(6,6,'R','appeared',10,'warm',20.0,0.9,1.0,NULL,'world',1795473399614446991);
INSERT INTO "events" VALUES(7,7,'ANNE','appeared',10,'true',NULL,1.0,1.0,NULL,'beliefs',1795473399616238510);
INSERT INTO "events" VALUES(8,8,'ANNE','appeared',10,'true',NULL,1.0,1.0,NULL,'beliefs',1795473399616238510);
INSERT INTO "events" VALUES(9,9,'ANNE','appeared',10,'true',NULL,1.0,1.0,NULL,'beliefs',1795473399616238510);
INSERT INTO "events" VALUES(10,10,'ANNE','appeared',10,'true',NULL,1.0,1.0,NULL,'beliefs',1795473399616238510);
INSERT INTO "events" VALUES(11,11,'ANNE','appeared',10,'red',NULL,1.0,1.0,NULL,'beliefs',1795473399616238510);
INSERT INTO "events" VALUES(12,12,'ANNE','appeared',10,'warm',20.0,0.9,1.0,NULL,'beliefs',1795473399616238510);
INSERT INTO "events" VALUES(13,13,'ANNE>BOB','appeared',10,'true',NULL,1.0,1.0,NULL,'beliefs',1795473399616238510);
INSERT INTO "events" VALUES(14,14,'ANNE>BOB','appeared',10,'true',NULL,1.0,1.0,NULL,'beliefs',1795473399616238510);
INSERT INTO "events" VALUES(15,15,'ANNE>BOB','appeared',10,'true',NULL,1.0,1.0,NULL,'beliefs',1795473399616238510);
INSERT INTO "events" VALUES(16,16,'ANNE>BOB','appeared',10,'true',NULL,1.0,1.0,NULL,'beliefs',1795473399616238510);
INSERT INTO "events" VALUES(17,17,'ANNE>BOB','appeared',10,'red',NULL,1.0,1.0,NULL,'beliefs',1795473399616238510);
INSERT INTO "events" VALUES(18,18,'ANNE>BOB','appeared',10,'warm',20.0,0.9,1.0,NULL,'beliefs',1795473399616238510);
INSERT INTO "events" VALUES(19,19,'BOB','appeared',10,'true',NULL,1.0,1.0,NULL,'beliefs',1795473399616238510);
INSERT INTO "events" VALUES(20,20,'BOB','appeared',10,'true',NULL,1.0,1.0,NULL,'beliefs',1795473399616238510);
INSERT INTO "events" VALUES(21,21,'BOB','appeared',10,'true',NULL,1.0,1.0,NULL,'beliefs',1795473399616238510);
INSERT INTO "events" VALUES(22,22,'BOB','appeared',10,'true',NULL,1.0,1.0,NULL,'beliefs',1795473399616238510);
INSERT INTO "events" VALUES(23,23,'BOB','appeared',10,'red',NULL,1.0,1.0,NULL,'beliefs',1795473399616238510);
INSERT INTO "events" VALUES(24,24,'BOB','appeared',10,'warm',20.0,0.9,1.0,NULL,'beliefs',1795473399616238510);
INSERT INTO "events" VALUES(25,25,'BOB>ANNE','appeared',10,'true',NULL,1.0,1.0,NULL,'beliefs',1795473399616238510);
INSERT INTO "events" VALUES(26,26,'BOB>ANNE','appeared',10,'true',NULL,1.0,1.0,NULL,'beliefs',1795473399616238510);
INSERT INTO "events" VALUES(27,27,'BOB>ANNE','appeared',10,'true',NULL,1.0,1.0,NULL,'beliefs',1795473399616238510);
INSERT INTO "events" VALUES(28,28,'BOB>ANNE','appeared',10,'true',NULL,1.0,1.0,NULL,'beliefs',1795473399616238510);
INSERT INTO "events" VALUES(29,29,'BOB>ANNE','appeared',10,'red',NULL,1.0,1.0,NULL,'beliefs',1795473399616238510);
INSERT INTO "events" VALUES(30,30,'BOB>ANNE','appeared',10,'warm',20.0,0.9,1.0,NULL,'beliefs',1795473399616238510);
INSERT INTO "events" VALUES(31,31,'R','appeared',20,'true',NULL,1.0,1.0,NULL,'world',1795473399645784883);
INSERT INTO "events" VALUES(32,32,'ANNE','appeared',20,'true',NULL,0.9,1.0,NULL,'beliefs',1795473399646320421);
INSERT INTO "events" VALUES(33,33,'ANNE>BOB','appeared',20,'true',NULL,0.9,1.0,NULL,'beliefs',1795473399646320421);
INSERT INTO "events" VALUES(34,34,'BOB','appeared',20,'true',NULL,1.0,1.0,NULL,'beliefs',1795473399646320421);
INSERT INTO "events" VALUES(35,35,'BOB>ANNE','appeared',20,'true',NULL,0.9,1.0,NULL,'beliefs',1795473399646320421);
INSERT INTO "events" VALUES(36,2,'R','ended',30,'true',NULL,1.0,1.0,NULL,'world',1795473399656338217);
INSERT INTO "events" VALUES(37,36,'R','appeared',30,'true',NULL,1.0,1.0,NULL,'world',1795473399656338217);
INSERT INTO "events" VALUES(38,5,'R','changed',30,'blue',NULL,1.0,1.0,'red','world',1795473399656338217);
INSERT INTO "events" VALUES(39,37,'ANNE','appeared',30,'true',NULL,0.9,1.0,NULL,'beliefs',1795473399656854406);
INSERT INTO "events" VALUES(40,38,'ANNE>BOB','appeared',30,'true',NULL,0.9,1.0,NULL,'beliefs',1795473399656854406);
INSERT INTO "events" VALUES(41,39,'BOB','appeared',30,'true',NULL,1.0,1.0,NULL,'beliefs',1795473399656854406);
INSERT INTO "events" VALUES(42,40,'BOB>ANNE','appeared',30,'true',NULL,0.9,1.0,NULL,'beliefs',1795473399656854406);
INSERT INTO "events" VALUES(43,41,'R','appeared',40,'true',NULL,1.0,1.0,NULL,'world',1795473399666486357);
INSERT INTO "events" VALUES(44,5,'R','changed',40,'green',NULL,1.0,1.0,'blue','world',1795473399666486357);
INSERT INTO "events" VALUES(45,42,'ANNE','appeared',40,'true',NULL,1.0,1.0,NULL,'beliefs',1795473399667061694);
CREATE TABLE fact_keys (
	id INTEGER NOT NULL, 
	agent_id TEXT NOT NULL, 
	subject_id TEXT NOT NULL, 
	subject_owner_id TEXT DEFAULT ('') NOT NULL, 
	property TEXT NOT NULL, 
	sub_property TEXT DEFAULT ('') NOT NULL, 
	target_id TEXT DEFAULT ('') NOT NULL, 
	target_owner_id TEXT DEFAULT ('') NOT NULL, 
	property_type TEXT DEFAULT ('') NOT NULL, 
	CONSTRAINT pk_fact_keys PRIMARY KEY (id), 
	CONSTRAINT ck_fact_keys_key_not_empty CHECK (subject_id <> '' AND property <> ''), 
	CONSTRAINT fk_fact_keys_agent_id_agents FOREIGN KEY(agent_id) REFERENCES agents (id) ON DELETE CASCADE
);
INSERT INTO "fact_keys" VALUES(1,'R','ANNE','','IsInRoom','','LAB','','');
INSERT INTO "fact_keys" VALUES(2,'R','BOB','','IsInRoom','','LAB','','');
INSERT INTO "fact_keys" VALUES(3,'R','BOX','','IsInRoom','','LAB','','');
INSERT INTO "fact_keys" VALUES(4,'R','MUG','','IsInRoom','','LAB','','');
INSERT INTO "fact_keys" VALUES(5,'R','MUG','','Color','','','','');
INSERT INTO "fact_keys" VALUES(6,'R','MUG','','Temperature','','','','');
INSERT INTO "fact_keys" VALUES(7,'ANNE','ANNE','','IsInRoom','','LAB','','');
INSERT INTO "fact_keys" VALUES(8,'ANNE','BOB','','IsInRoom','','LAB','','');
INSERT INTO "fact_keys" VALUES(9,'ANNE','BOX','','IsInRoom','','LAB','','');
INSERT INTO "fact_keys" VALUES(10,'ANNE','MUG','','IsInRoom','','LAB','','');
INSERT INTO "fact_keys" VALUES(11,'ANNE','MUG','','Color','','','','');
INSERT INTO "fact_keys" VALUES(12,'ANNE','MUG','','Temperature','','','','');
INSERT INTO "fact_keys" VALUES(13,'ANNE>BOB','ANNE','','IsInRoom','','LAB','','');
INSERT INTO "fact_keys" VALUES(14,'ANNE>BOB','BOB','','IsInRoom','','LAB','','');
INSERT INTO "fact_keys" VALUES(15,'ANNE>BOB','BOX','','IsInRoom','','LAB','','');
INSERT INTO "fact_keys" VALUES(16,'ANNE>BOB','MUG','','IsInRoom','','LAB','','');
INSERT INTO "fact_keys" VALUES(17,'ANNE>BOB','MUG','','Color','','','','');
INSERT INTO "fact_keys" VALUES(18,'ANNE>BOB','MUG','','Temperature','','','','');
INSERT INTO "fact_keys" VALUES(19,'BOB','ANNE','','IsInRoom','','LAB','','');
INSERT INTO "fact_keys" VALUES(20,'BOB','BOB','','IsInRoom','','LAB','','');
INSERT INTO "fact_keys" VALUES(21,'BOB','BOX','','IsInRoom','','LAB','','');
INSERT INTO "fact_keys" VALUES(22,'BOB','MUG','','IsInRoom','','LAB','','');
INSERT INTO "fact_keys" VALUES(23,'BOB','MUG','','Color','','','','');
INSERT INTO "fact_keys" VALUES(24,'BOB','MUG','','Temperature','','','','');
INSERT INTO "fact_keys" VALUES(25,'BOB>ANNE','ANNE','','IsInRoom','','LAB','','');
INSERT INTO "fact_keys" VALUES(26,'BOB>ANNE','BOB','','IsInRoom','','LAB','','');
INSERT INTO "fact_keys" VALUES(27,'BOB>ANNE','BOX','','IsInRoom','','LAB','','');
INSERT INTO "fact_keys" VALUES(28,'BOB>ANNE','MUG','','IsInRoom','','LAB','','');
INSERT INTO "fact_keys" VALUES(29,'BOB>ANNE','MUG','','Color','','','','');
INSERT INTO "fact_keys" VALUES(30,'BOB>ANNE','MUG','','Temperature','','','','');
INSERT INTO "fact_keys" VALUES(31,'R','MUG','','IsIn','','BOX','','');
INSERT INTO "fact_keys" VALUES(32,'ANNE','MUG','','IsIn','','BOX','','');
INSERT INTO "fact_keys" VALUES(33,'ANNE>BOB','MUG','','IsIn','','BOX','','');
INSERT INTO "fact_keys" VALUES(34,'BOB','MUG','','IsIn','','BOX','','');
INSERT INTO "fact_keys" VALUES(35,'BOB>ANNE','MUG','','IsIn','','BOX','','');
INSERT INTO "fact_keys" VALUES(36,'R','BOB','','IsInRoom','','HALL','','');
INSERT INTO "fact_keys" VALUES(37,'ANNE','BOB','','IsInRoom','','HALL','','');
INSERT INTO "fact_keys" VALUES(38,'ANNE>BOB','BOB','','IsInRoom','','HALL','','');
INSERT INTO "fact_keys" VALUES(39,'BOB','BOB','','IsInRoom','','HALL','','');
INSERT INTO "fact_keys" VALUES(40,'BOB>ANNE','BOB','','IsInRoom','','HALL','','');
INSERT INTO "fact_keys" VALUES(41,'R','BOX','','IsClosed','','','','');
INSERT INTO "fact_keys" VALUES(42,'ANNE','BOX','','IsClosed','','','','');
CREATE TABLE fact_samples (
	fact_id BIGINT NOT NULL, 
	until_ns BIGINT NOT NULL, 
	value_num FLOAT, 
	confidence FLOAT NOT NULL, 
	observability FLOAT NOT NULL, 
	CONSTRAINT pk_fact_samples PRIMARY KEY (fact_id, until_ns)
)
 WITHOUT ROWID

;
INSERT INTO "fact_samples" VALUES(1,20,NULL,1.0,1.0);
INSERT INTO "fact_samples" VALUES(1,40,NULL,0.9,1.0);
CREATE TABLE facts (
	id INTEGER NOT NULL, 
	key_id BIGINT NOT NULL, 
	value_text TEXT NOT NULL, 
	value_num FLOAT, 
	confidence FLOAT NOT NULL, 
	observability FLOAT NOT NULL, 
	valid_from_ns BIGINT NOT NULL, 
	valid_to_ns BIGINT, 
	recorded_ns BIGINT NOT NULL, 
	source TEXT NOT NULL, 
	CONSTRAINT pk_facts PRIMARY KEY (id), 
	CONSTRAINT ck_facts_confidence_range CHECK (confidence >= 0 AND confidence <= 1), 
	CONSTRAINT ck_facts_observability_range CHECK (observability >= 0 AND observability <= 1), 
	CONSTRAINT ck_facts_valid_interval CHECK (valid_to_ns IS NULL OR valid_to_ns >= valid_from_ns)
);
INSERT INTO "facts" VALUES(1,1,'true',NULL,1.0,1.0,10,NULL,1795473399614446991,'world');
INSERT INTO "facts" VALUES(2,2,'true',NULL,1.0,1.0,10,30,1795473399614446991,'world');
INSERT INTO "facts" VALUES(3,3,'true',NULL,1.0,1.0,10,NULL,1795473399614446991,'world');
INSERT INTO "facts" VALUES(4,4,'true',NULL,1.0,1.0,10,NULL,1795473399614446991,'world');
INSERT INTO "facts" VALUES(5,5,'red',NULL,1.0,1.0,10,30,1795473399614446991,'world');
INSERT INTO "facts" VALUES(6,6,'warm',20.0,0.9,1.0,10,NULL,1795473399614446991,'world');
INSERT INTO "facts" VALUES(7,31,'true',NULL,1.0,1.0,20,NULL,1795473399645784883,'world');
INSERT INTO "facts" VALUES(8,36,'true',NULL,1.0,1.0,30,NULL,1795473399656338217,'world');
INSERT INTO "facts" VALUES(9,5,'blue',NULL,1.0,1.0,30,40,1795473399656338217,'world');
INSERT INTO "facts" VALUES(10,41,'true',NULL,1.0,1.0,40,NULL,1795473399666486357,'world');
INSERT INTO "facts" VALUES(11,5,'green',NULL,1.0,1.0,40,NULL,1795473399666486357,'world');
INSERT INTO "facts" VALUES(12,19,'true',NULL,0.9,1.0,10,NULL,1795473399667061694,'beliefs');
INSERT INTO "facts" VALUES(13,23,'blue',NULL,1.0,1.0,30,NULL,1795473399667061694,'beliefs');
INSERT INTO "facts" VALUES(14,13,'true',NULL,0.81,1.0,10,NULL,1795473399667061694,'beliefs');
INSERT INTO "facts" VALUES(15,25,'true',NULL,0.81,1.0,10,NULL,1795473399667061694,'beliefs');
INSERT INTO "facts" VALUES(16,17,'blue',NULL,0.9,1.0,30,NULL,1795473399667061694,'beliefs');
INSERT INTO "facts" VALUES(17,29,'blue',NULL,0.9,1.0,30,NULL,1795473399667061694,'beliefs');
CREATE TABLE ontology (
	entity_class TEXT NOT NULL, 
	individual TEXT NOT NULL, 
	instantiated BOOLEAN DEFAULT (false) NOT NULL, 
	CONSTRAINT pk_ontology PRIMARY KEY (entity_class, individual), 
	CONSTRAINT ck_ontology_not_empty CHECK (entity_class <> '' AND individual <> '')
);
CREATE TABLE properties (
	entity_id TEXT NOT NULL, 
	"key" TEXT NOT NULL, 
	value TEXT NOT NULL, 
	CONSTRAINT pk_properties PRIMARY KEY (entity_id, "key"), 
	CONSTRAINT ck_properties_key_not_empty CHECK (key <> ''), 
	CONSTRAINT fk_properties_entity_id_entities FOREIGN KEY(entity_id) REFERENCES entities (id) ON DELETE CASCADE
);
CREATE TABLE settings (
	scope TEXT NOT NULL, 
	"key" TEXT NOT NULL, 
	value_json TEXT NOT NULL, 
	CONSTRAINT pk_settings PRIMARY KEY (scope, "key")
);
INSERT INTO "settings" VALUES('beliefs','enabled','true');
INSERT INTO "settings" VALUES('beliefs','depth','2');
INSERT INTO "settings" VALUES('beliefs','copresence','["IsInRoom"]');
INSERT INTO "settings" VALUES('beliefs','containment','["IsIn", "IsOn"]');
INSERT INTO "settings" VALUES('beliefs','visibility','{"IsVisibleBy": "target", "CanSee": "subject", "IsLookingToward": "subject"}');
INSERT INTO "settings" VALUES('beliefs','closed','"IsClosed"');
INSERT INTO "settings" VALUES('beliefs','refute_by_target','["IsOn"]');
INSERT INTO "settings" VALUES('beliefs','self_perception','false');
INSERT INTO "settings" VALUES('beliefs','share_rows','true');
CREATE TABLE "store_state" (
	id INTEGER NOT NULL, 
	cache_epoch BIGINT DEFAULT 0 NOT NULL, 
	control_version BIGINT DEFAULT 0 NOT NULL, 
	CONSTRAINT pk_store_state PRIMARY KEY (id), 
	CONSTRAINT ck_store_state_single_row CHECK (id = 1)
);
INSERT INTO "store_state" VALUES(1,0,0);
CREATE INDEX ix_ontology_individual ON ontology (individual);
CREATE INDEX ix_properties_key_value ON properties ("key", value);
CREATE INDEX ix_fact_keys_property ON fact_keys (agent_id, property);
CREATE INDEX ix_fact_keys_subject ON fact_keys (subject_id, agent_id);
CREATE INDEX ix_fact_keys_target ON fact_keys (target_id, agent_id);
CREATE UNIQUE INDEX uq_fact_keys_identity ON fact_keys (agent_id, subject_id, subject_owner_id, property, sub_property, target_id, target_owner_id);
CREATE INDEX ix_events_agent_stamp ON events (agent_id, stamp_ns);
CREATE INDEX ix_events_key_stamp ON events (key_id, stamp_ns);
CREATE INDEX ix_events_stamp ON events (stamp_ns);
CREATE INDEX ix_facts_key_from ON facts (key_id, valid_from_ns, id);
CREATE UNIQUE INDEX uq_facts_open_key ON facts (key_id) WHERE valid_to_ns IS NULL;
CREATE INDEX ix_belief_chain_member_id ON belief_chain (member_id);
CREATE UNIQUE INDEX uq_belief_follow_open_hkey ON belief_follow (hkey) WHERE to_ns IS NULL;
CREATE INDEX ix_belief_follow_hkey_from ON belief_follow (hkey, from_ns);
CREATE INDEX ix_belief_follow_self_holder ON belief_follow (self_key, holder_id);
CREATE VIEW fact_history AS SELECT k.agent_id, k.subject_id, k.subject_owner_id, k.property, k.property_type, k.sub_property, k.target_id, k.target_owner_id, f.value_text, f.value_num, f.confidence, f.observability, f.valid_from_ns, f.valid_to_ns, f.recorded_ns, f.source, f.id AS fact_id, k.id AS key_id FROM facts f JOIN fact_keys k ON k.id = f.key_id UNION ALL SELECT k.agent_id, k.subject_id, k.subject_owner_id, k.property, k.property_type, k.sub_property, k.target_id, k.target_owner_id, f.value_text, f.value_num, MIN(1.0, f.confidence * w.pconf), f.observability, MAX(f.valid_from_ns, w.from_ns), CASE WHEN w.to_ns IS NULL THEN f.valid_to_ns WHEN f.valid_to_ns IS NULL THEN w.to_ns ELSE MIN(f.valid_to_ns, w.to_ns) END, f.recorded_ns, 'beliefs', f.id, k.id FROM belief_follow w JOIN fact_keys k ON k.id = w.hkey JOIN facts f ON f.key_id = w.self_key AND (w.to_ns IS NULL OR (f.valid_from_ns < w.to_ns AND w.to_ns > w.from_ns)) AND (f.valid_to_ns IS NULL OR f.valid_to_ns > w.from_ns);
CREATE VIEW current_facts AS SELECT k.agent_id, k.subject_id, k.subject_owner_id, k.property, k.property_type, k.sub_property, k.target_id, k.target_owner_id, f.value_text, f.value_num, f.confidence, f.observability, f.valid_from_ns, f.valid_to_ns, f.recorded_ns, f.source, f.id AS fact_id, k.id AS key_id FROM facts f JOIN fact_keys k ON k.id = f.key_id WHERE f.valid_to_ns IS NULL UNION ALL SELECT k.agent_id, k.subject_id, k.subject_owner_id, k.property, k.property_type, k.sub_property, k.target_id, k.target_owner_id, f.value_text, f.value_num, MIN(1.0, f.confidence * w.pconf), f.observability, MAX(f.valid_from_ns, w.from_ns), CASE WHEN w.to_ns IS NULL THEN f.valid_to_ns WHEN f.valid_to_ns IS NULL THEN w.to_ns ELSE MIN(f.valid_to_ns, w.to_ns) END, f.recorded_ns, 'beliefs', f.id, k.id FROM belief_follow w JOIN fact_keys k ON k.id = w.hkey JOIN facts f ON f.key_id = w.self_key AND (w.to_ns IS NULL OR (f.valid_from_ns < w.to_ns AND w.to_ns > w.from_ns)) AND (f.valid_to_ns IS NULL OR f.valid_to_ns > w.from_ns) AND w.to_ns IS NULL AND f.valid_to_ns IS NULL;
CREATE VIEW memory AS SELECT k.agent_id, k.subject_id, k.subject_owner_id, k.property, k.property_type, k.sub_property, k.target_id, k.target_owner_id, f.value_text, f.value_num, f.confidence, f.observability, f.valid_from_ns, f.valid_to_ns, f.recorded_ns, f.source, f.id AS fact_id, k.id AS key_id FROM facts f JOIN fact_keys k ON k.id = f.key_id WHERE f.valid_to_ns IS NOT NULL UNION ALL SELECT k.agent_id, k.subject_id, k.subject_owner_id, k.property, k.property_type, k.sub_property, k.target_id, k.target_owner_id, f.value_text, f.value_num, MIN(1.0, f.confidence * w.pconf), f.observability, MAX(f.valid_from_ns, w.from_ns), CASE WHEN w.to_ns IS NULL THEN f.valid_to_ns WHEN f.valid_to_ns IS NULL THEN w.to_ns ELSE MIN(f.valid_to_ns, w.to_ns) END, f.recorded_ns, 'beliefs', f.id, k.id FROM belief_follow w JOIN fact_keys k ON k.id = w.hkey JOIN facts f ON f.key_id = w.self_key AND (w.to_ns IS NULL OR (f.valid_from_ns < w.to_ns AND w.to_ns > w.from_ns)) AND (f.valid_to_ns IS NULL OR f.valid_to_ns > w.from_ns) AND (w.to_ns IS NOT NULL OR f.valid_to_ns IS NOT NULL);
CREATE VIEW event_log AS SELECT e.id, e.agent_id, e.kind, e.stamp_ns, k.subject_id, k.subject_owner_id, k.property, k.property_type, k.sub_property, k.target_id, k.target_owner_id, e.value_text, e.value_num, e.confidence, e.observability, e.previous_text, e.source, e.recorded_ns, e.key_id FROM events e JOIN fact_keys k ON k.id = e.key_id UNION ALL SELECT e.id, k.agent_id, e.kind, e.stamp_ns, k.subject_id, k.subject_owner_id, k.property, k.property_type, k.sub_property, k.target_id, k.target_owner_id, e.value_text, e.value_num, MIN(1.0, e.confidence * w.pconf), e.observability, e.previous_text, 'beliefs', e.recorded_ns, k.id FROM belief_follow w JOIN fact_keys k ON k.id = w.hkey JOIN events e ON e.key_id = w.self_key AND e.kind <> 'event' AND e.stamp_ns >= w.events_from_ns AND (w.events_to_ns IS NULL OR e.stamp_ns <= w.events_to_ns);
CREATE INDEX ix_control_commands_pending ON control_commands (state, id);
CREATE VIEW "fact_table_R" AS SELECT * FROM current_facts WHERE agent_id = (SELECT id FROM agents WHERE num = 1);
CREATE VIEW "memory_table_R" AS SELECT * FROM memory WHERE agent_id = (SELECT id FROM agents WHERE num = 1);
CREATE VIEW "events_table_R" AS SELECT * FROM event_log WHERE agent_id = (SELECT id FROM agents WHERE num = 1);
CREATE VIEW "fact_table_ANNE" AS SELECT * FROM current_facts WHERE agent_id = (SELECT id FROM agents WHERE num = 2);
CREATE VIEW "memory_table_ANNE" AS SELECT * FROM memory WHERE agent_id = (SELECT id FROM agents WHERE num = 2);
CREATE VIEW "events_table_ANNE" AS SELECT * FROM event_log WHERE agent_id = (SELECT id FROM agents WHERE num = 2);
CREATE VIEW "fact_table_BOB" AS SELECT * FROM current_facts WHERE agent_id = (SELECT id FROM agents WHERE num = 3);
CREATE VIEW "memory_table_BOB" AS SELECT * FROM memory WHERE agent_id = (SELECT id FROM agents WHERE num = 3);
CREATE VIEW "events_table_BOB" AS SELECT * FROM event_log WHERE agent_id = (SELECT id FROM agents WHERE num = 3);
CREATE VIEW "fact_table_ANNE>BOB" AS SELECT * FROM current_facts WHERE agent_id = (SELECT id FROM agents WHERE num = 4);
CREATE VIEW "memory_table_ANNE>BOB" AS SELECT * FROM memory WHERE agent_id = (SELECT id FROM agents WHERE num = 4);
CREATE VIEW "events_table_ANNE>BOB" AS SELECT * FROM event_log WHERE agent_id = (SELECT id FROM agents WHERE num = 4);
CREATE VIEW "fact_table_BOB>ANNE" AS SELECT * FROM current_facts WHERE agent_id = (SELECT id FROM agents WHERE num = 5);
CREATE VIEW "memory_table_BOB>ANNE" AS SELECT * FROM memory WHERE agent_id = (SELECT id FROM agents WHERE num = 5);
CREATE VIEW "events_table_BOB>ANNE" AS SELECT * FROM event_log WHERE agent_id = (SELECT id FROM agents WHERE num = 5);
COMMIT;
