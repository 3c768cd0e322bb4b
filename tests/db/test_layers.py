"""``toaster.connect`` (the composition root) is what gives every store the belief rule; the
database layer imports nothing from the layers above it (tests/test_architecture.py)."""

from __future__ import annotations

import pytest

import toaster
from toaster.app import session
from toaster.db import open_database
from toaster.rules.hook import BeliefRule

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)


def test_connect_installs_the_belief_rule_and_the_bare_opener_none(db_url: str) -> None:
    with toaster.connect(db_url) as db:
        assert db.rules == session.RULES
        assert [type(rule) for rule in db.store()._rules] == [BeliefRule]
    with open_database(db_url) as bare:
        assert bare.store()._rules == []
