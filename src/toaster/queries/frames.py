"""``to_dataframe``: rows from any query as a pandas DataFrame (pandas is an optional extra)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, NamedTuple

from toaster.errors import MissingDependencyError


def to_dataframe(rows: Sequence[NamedTuple], columns: Sequence[str] | None = None) -> Any:
    """A DataFrame with one column per field of the rows (``*_ns`` columns stay integers)."""
    try:
        import pandas as pd
    except ImportError:
        package = "pandas"
        raise MissingDependencyError(package, package, "to_dataframe") from None
    names = list(columns) if columns is not None else list(rows[0]._fields) if rows else []
    return pd.DataFrame.from_records([tuple(r) for r in rows], columns=names)
