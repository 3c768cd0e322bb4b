"""Exports: every kind and format reads back into equal rows, into pandas and into a database."""

from __future__ import annotations

from pathlib import Path

import pytest

import toaster
from tests.output.conftest import T0, S
from toaster import Fact
from toaster.errors import InvalidInputError, UnknownAgentError
from toaster.export import export, read_rows, select_rows
from toaster.queries import history, to_dataframe


@pytest.mark.parametrize("fmt", ["csv", "jsonl", "parquet"])
def test_every_kind_round_trips(run_db: toaster.Database, tmp_path: Path, fmt: str) -> None:
    """Written rows read back equal, None and integer nanoseconds included."""
    for kind in ("facts", "memory", "history", "events"):
        rows = select_rows(run_db, kind)
        assert rows, kind
        result = export(run_db, kind, tmp_path / f"{kind}.{fmt}")
        assert result.rows == len(rows)
        assert read_rows(result.path, kind) == rows


@pytest.mark.parametrize("fmt", ["csv", "jsonl", "parquet"])
def test_exports_read_into_pandas(run_db: toaster.Database, tmp_path: Path, fmt: str) -> None:
    """pandas reads each format into the frame to_dataframe builds."""
    pd = pytest.importorskip("pandas")
    rows = select_rows(run_db, "history", agent="pr2", since=T0 + 3 * S, until=T0 + 9 * S)
    path = export(run_db, "history", tmp_path / f"h.{fmt}", agent="pr2", since=T0 + 3 * S,
                  until=T0 + 9 * S).path
    reader = {"csv": pd.read_csv, "parquet": pd.read_parquet,
              "jsonl": lambda p: pd.read_json(p, lines=True, dtype=False)}[fmt]
    got = reader(path)
    want = to_dataframe(rows)
    assert list(got.columns) == list(want.columns)
    assert list(got.valid_from_ns) == list(want.valid_from_ns)
    assert list(got.value_text) == list(want.value_text)
    assert got.valid_from_ns.dtype.kind == "i"


def test_filters_and_errors(run_db: toaster.Database, tmp_path: Path) -> None:
    """Filters as in get-info; bad input names the value and the fix."""
    rows = read_rows(export(run_db, "events", tmp_path / "e.jsonl", agent="alice").path,
                     "events")
    assert [(e.agent_id, e.kind, e.target_id) for e in rows] == [
        ("alice", "appeared", "table")]
    with pytest.raises(UnknownAgentError, match="unknown agent 'carol'"):
        export(run_db, "memory", tmp_path / "m.csv", agent="carol")
    with pytest.raises(InvalidInputError, match="unknown export file suffix of .*m.xlsx"):
        export(run_db, "memory", tmp_path / "m.xlsx")
    with pytest.raises(InvalidInputError, match="unknown export kind 'beliefs'"):
        export(run_db, "beliefs", tmp_path / "m.csv")
    with pytest.raises(InvalidInputError, match="current facts have no time window"):
        export(run_db, "facts", tmp_path / "f.csv", since=T0)


def test_history_export_rebuilds_the_store(run_db: toaster.Database, tmp_path: Path) -> None:
    """Replaying an exported history through the store API into a new database gives the same
    intervals back."""
    path = export(run_db, "history", tmp_path / "h.parquet").path
    rows = read_rows(path, "history")
    copy = toaster.connect(f"sqlite:///{tmp_path / 'copy.db'}")
    try:
        store = copy.store()
        for entity in toaster.queries.entities(run_db):
            store.add_entity(entity.id, entity.kind, is_self=entity.id == "pr2", t_ns=T0)
        steps = [(r.valid_from_ns, 1, r) for r in rows]
        steps += [(r.valid_to_ns, 0, r) for r in rows if r.valid_to_ns is not None]
        for t_ns, opens, r in sorted(steps, key=lambda s: (s[0], s[1])):
            if opens:
                store.assert_fact(r.agent_id, Fact(*r.to_fact()), t_ns=t_ns, source=r.source)
            else:
                store.retract_facts(r.agent_id, r.property, r.subject_id, r.target_id,
                                    t_ns=t_ns, source=r.source)
        def strip(rs: list) -> list:
            return sorted(r._replace(recorded_ns=0) for r in rs)

        assert strip(history(copy)) == strip(rows)
    finally:
        copy.close()
