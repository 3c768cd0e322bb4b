"""Reading the JSON and YAML files users hand to toaster (batches, scenarios), with one-line
errors that name the file and what is wrong."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import yaml

from toaster.errors import FileFormatError


def read_document(path: str | Path, what: str = "file") -> Any:
    """Parse ``path`` as JSON (``.json``) or YAML (any other suffix).

    Raises :class:`FileFormatError` ("cannot read scenario 'x.yaml': ..." for a missing or
    unreadable file, "... is not valid YAML/JSON (...): fix the syntax" for a parse error).
    """
    path = Path(path)
    try:
        body = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        reason = getattr(exc, "strerror", None) or str(exc).splitlines()[0]
        msg = f"cannot read {what} {str(path)!r}: {reason}"
        raise FileFormatError(msg) from None
    try:
        return json.loads(body) if path.suffix.lower() == ".json" else yaml.safe_load(body)
    except (json.JSONDecodeError, yaml.YAMLError) as exc:
        first = str(exc).strip().splitlines()[0]
        msg = f"cannot read {what} {str(path)!r}: not valid YAML/JSON ({first}): fix the syntax"
        raise FileFormatError(msg) from None
