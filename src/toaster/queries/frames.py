"""``to_dataframe``: rows from any query as a pandas DataFrame (pandas is an optional extra).

Column types follow the rows' fields, as in a Parquet export (:mod:`toaster.outputs.export`): text
stays text (an empty owner is ``""``, never NaN), integers stay exact integers (``*_ns``
times in nanoseconds; a field that may be None, such as ``valid_to_ns`` of an open interval,
is pandas' nullable ``Int64`` with ``<NA>``, never a float), floats are floats. With
``times=True`` each ``X_ns`` field also gets a column ``X`` of ``datetime64[ns, UTC]``
(``NaT`` where the time is None).
"""

from __future__ import annotations

import typing
from collections.abc import Sequence
from typing import Any, NamedTuple

from toaster.extras import require

#: Fields ending so hold integer nanoseconds since the epoch (UTC).
TIME_SUFFIX = "_ns"


def field_kinds(rtype: type) -> dict[str, tuple[type, bool]]:
    """Each annotated field's base type (str, int, float, bool) and whether it may be None;
    empty for a tuple type without annotations."""
    try:
        hints = typing.get_type_hints(rtype)
    except (NameError, TypeError):
        return {}
    out: dict[str, tuple[type, bool]] = {}
    for name in getattr(rtype, "_fields", ()):
        if name not in hints:
            continue
        args = typing.get_args(hints[name])
        base = [a for a in args if a is not type(None)]
        out[name] = (base[0], True) if base else (hints[name], False)
    return out


def time_columns(fields: Sequence[str]) -> dict[str, str]:
    """``{"valid_from_ns": "valid_from", ...}``: each time field and its timestamp column."""
    return {f: f[: -len(TIME_SUFFIX)] for f in fields if f.endswith(TIME_SUFFIX)}


def _integers(values: list[Any], kind: tuple[type, bool] | None) -> bool:
    if kind is not None:
        return kind[0] is int
    present = [v for v in values if v is not None]
    return bool(present) and all(type(v) is int for v in present)


def to_dataframe(
    rows: Sequence[NamedTuple], columns: Sequence[str] | None = None, *, times: bool = False
) -> Any:
    """A DataFrame with one column per field of the rows, typed as described in the module
    docstring (``*_ns`` columns stay exact integers; ``times`` adds timestamp columns)."""
    require("pandas", "to_dataframe")
    import numpy as np
    import pandas as pd

    names = list(columns) if columns is not None else list(rows[0]._fields) if rows else []
    kinds = field_kinds(type(rows[0])) if rows and columns is None else {}
    data: dict[str, Any] = {}
    raw = {name: [row[i] for row in rows] for i, name in enumerate(names)}
    for name, values in raw.items():
        if _integers(values, kinds.get(name)):
            nullable = kinds.get(name, (int, True))[1] or None in values
            data[name] = pd.array(values, dtype="Int64" if nullable else "int64")
        else:
            data[name] = pd.Series(values, dtype=object if not values else None)
    frame = pd.DataFrame(data, columns=names)
    if times:
        for field, column in time_columns(names).items():
            nat = np.iinfo(np.int64).min  # numpy's NaT
            ns = np.array([nat if v is None else v for v in raw[field]], dtype=np.int64)
            frame[column] = pd.Series(ns.view("M8[ns]"), index=frame.index).dt.tz_localize("UTC")
    return frame
