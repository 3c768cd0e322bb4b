"""Exports: every kind and format reads back into equal rows, into pandas and into a database."""

from __future__ import annotations

from pathlib import Path

import pytest

import toaster
from tests.outputs.conftest import T0, S
from toaster import Fact, FactRow
from toaster.errors import InvalidInputError, UnknownAgentError
from toaster.outputs.export import export, read_frame, read_rows, select_rows
from toaster.queries import history, to_dataframe

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)


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
    """read_frame gives, for every format, the frame to_dataframe builds from the query: empty
    owners stay "", an open interval's end is <NA> (not a NaN float) and every nanosecond of
    every time survives."""
    pd = pytest.importorskip("pandas")
    from pandas.testing import assert_frame_equal

    rows = select_rows(run_db, "history", agent="pr2", since=T0 + 3 * S)
    assert any(r.valid_to_ns is None for r in rows) and any(r.valid_to_ns for r in rows)
    path = export(run_db, "history", tmp_path / f"h.{fmt}", agent="pr2", since=T0 + 3 * S).path
    want = to_dataframe(rows, times=True)
    got = read_frame(path, "history")
    assert_frame_equal(got, want)
    assert str(got.valid_to_ns.dtype) == "Int64"
    assert str(got.valid_from.dtype) == "datetime64[ns, UTC]"
    assert list(got.valid_to_ns) == [
        pd.NA if r.valid_to_ns is None else r.valid_to_ns for r in rows
    ]
    assert list(got.valid_from.astype("int64")) == [r.valid_from_ns for r in rows]
    assert set(got.subject_owner_id) == {""}
    fields = to_dataframe(rows)  # the fields only: exact integers, Int64 where None may be
    assert list(fields.columns) == list(FactRow._fields)
    assert (str(fields.valid_from_ns.dtype), str(fields.valid_to_ns.dtype)) == ("int64", "Int64")


def test_parquet_keeps_the_types(run_db: toaster.Database, tmp_path: Path) -> None:
    """The Parquet schema says what the columns are: times timestamp[ns, tz=UTC] beside the
    integer ns, null for an open interval; pandas.read_parquet alone gives nullable Int64."""
    pd = pytest.importorskip("pandas")
    pa = pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq
    from pandas.testing import assert_frame_equal

    rows = select_rows(run_db, "history")
    path = export(run_db, "history", tmp_path / "h.parquet").path
    schema = pq.read_schema(path)
    stamp = pa.timestamp("ns", tz="UTC")
    assert [schema.field(n).type for n in ("valid_from", "valid_to", "recorded")] == [stamp] * 3
    assert schema.field("valid_to_ns").type == pa.int64()
    assert schema.field("value_num").type == pa.float64()
    assert schema.field("subject_owner_id").type == pa.string()
    table = pq.read_table(path)
    assert table.column("valid_to_ns").null_count == sum(r.valid_to_ns is None for r in rows) > 0
    frame = pd.read_parquet(path)
    assert str(frame.valid_to_ns.dtype) == "Int64"
    assert frame.valid_to.isna().sum() == sum(r.valid_to_ns is None for r in rows)
    assert_frame_equal(frame, to_dataframe(rows, times=True))
    events = pq.read_schema(export(run_db, "events", tmp_path / "e.parquet").path)
    assert events.field("stamp").type == stamp
    assert events.field("id").type == pa.int64()


def test_csv_has_no_nan_for_empty_text(run_db: toaster.Database, tmp_path: Path) -> None:
    """Empty owners and absent numbers are empty cells, never 'nan'; read_frame reads the
    owners back as "" (pandas.read_csv alone would make them NaN)."""
    import csv

    pytest.importorskip("pandas")
    for kind in ("history", "events"):
        path = export(run_db, kind, tmp_path / f"{kind}.csv").path
        with path.open(newline="") as handle:
            cells = [cell for row in csv.reader(handle) for cell in row]
        assert not [c for c in cells if c.lower() in {"nan", "none", "null", "<na>"}]
        frame = read_frame(path, kind)
        assert set(frame.subject_owner_id) == {""}
        assert not frame.target_owner_id.isna().any()


def test_filters_and_errors(run_db: toaster.Database, tmp_path: Path) -> None:
    """Filters as in get-info; bad input names the value and the fix."""
    rows = read_rows(export(run_db, "events", tmp_path / "e.jsonl", agent="alice").path, "events")
    assert [(e.agent_id, e.kind, e.target_id) for e in rows] == [("alice", "appeared", "table")]
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
                store.retract_facts(
                    r.agent_id, r.property, r.subject_id, r.target_id, t_ns=t_ns, source=r.source
                )

        def strip(rs: list) -> list:
            return sorted(r._replace(recorded_ns=0) for r in rs)

        assert strip(history(copy)) == strip(rows)
    finally:
        copy.close()
