"""Batch files: the original's XML seeds and JSON/YAML equivalents, all or nothing."""

from __future__ import annotations

from pathlib import Path

import pytest

import toaster
from tests.conftest import shared_data
from toaster import queries as q
from toaster.db.seed import load_file
from toaster.errors import FileFormatError, InvalidInputError

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)


def test_original_xml_seeds(db: toaster.Database) -> None:
    """id_list, ontology and static_property from the original load with quotes stripped."""
    folder = shared_data("toaster-laas", "database_manager", "database")
    store = db.store()
    for name in ("id_list.xml", "ontology.xml", "static_property.xml"):
        load_file(store, folder / name)
    agents = {a.id: a.is_self for a in q.agents(db)}
    assert agents == {"PR2_ROBOT": True, "HERAKLES_HUMAN1": False, "HERAKLES_HUMAN2": False}
    cube = q.entities(db, "RED_CUBE")[0]
    assert (cube.kind, cube.name, cube.owner_id) == ("object", "RED_CUBE", "")
    assert [r.individual for r in q.descendants(db, "viewable")] == ["grey_tape", "red_tape"]
    assert ("agent", "human", False) in q.ontology(db, "agent")
    props = {(p.entity_id, p.key): p.value for p in q.properties(db)}
    assert props[("1", "color")] == "green" and props[("6", "linkType")] == "cube"
    assert props[("2", "linkedToId")] == "1"


def test_yaml_batch_with_timeline(db: toaster.Database, tmp_path: Path) -> None:
    """Entities, facts and a timeline with relative times load in one go."""
    path = tmp_path / "batch.yaml"
    path.write_text("""
base_time: 2026-01-01T00:00:00Z
entities:
  - {id: R, kind: robot, self: true}
  - {id: CUP}
  - {id: TABLE}
properties: [{entity: CUP, key: color, value: red}]
timeline:
  - at: 1s
    facts: [{subject: CUP, property: IsOn, target: TABLE, confidence: 0.5}]
  - at: 2.5s
    retract: [{subject: CUP, property: IsOn, target: NULL}]
""")
    report = load_file(db.store(), path)
    assert report == {"entities": 3, "properties": 1, "facts": 1, "retracted": 1}
    (row,) = q.history(db, "R")
    base = toaster.timeutil.parse_time("2026-01-01T00:00:00Z")
    assert (row.valid_from_ns - base, row.valid_to_ns - base, row.confidence) == (
        1_000_000_000,
        2_500_000_000,
        0.5,
    )


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("facts: [", "cannot read"),
        ("- just a list", "top level must be a mapping"),
        ("entitys: []", "unknown section"),
        (
            "entities: [{id: R, kind: robot, self: true}]\nfacts: [{subject: R, property: P, "
            "confidence: 2}]",
            r"facts\[0\]: invalid confidence 2",
        ),
        (
            "entities: [{id: R, kind: robot, self: true}]\ntimeline: [{at: soon, facts: []}]",
            "invalid time 'soon'",
        ),
    ],
)
def test_bad_files_write_nothing(
    db: toaster.Database, tmp_path: Path, content: str, message: str
) -> None:
    """A malformed file fails with a one-line error and leaves the database unchanged."""
    path = tmp_path / "bad.yaml"
    path.write_text(content)
    with pytest.raises((FileFormatError, InvalidInputError), match=message) as info:
        load_file(db.store(), path)
    assert "\n" not in str(info.value)
    assert q.entities(db) == []
