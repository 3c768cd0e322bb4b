"""ToM-bAbI stories replayed through the public API on both backends (a sample per file;
`python -m tools.tombabi` runs all of them)."""

from __future__ import annotations

import pytest

from tests.conftest import shared_data
from tools import tombabi

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)


@pytest.mark.shared_data
def test_tom_easy_sample_is_answered_and_perceivers_match(db_url: str) -> None:
    path = shared_data("tom-babi", "tom_easy.zip")
    out = tombabi.evaluate(path, db_url, limit=3)
    assert out["misses"] == []
    assert len(out["table"]) == 24  # 12 task/question files x noise 0 and 10
    assert all(ok == total and total > 0 for ok, total in out["table"].values())
    assert out["perceivers"]["lines"] > 0 and out["perceivers"]["mismatches"] == 0
