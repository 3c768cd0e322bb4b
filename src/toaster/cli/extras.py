"""Which optional extra each command needs for its arguments, checked (:func:`toaster.extras.
require`) before the command runs: before its database is opened, read or written."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

#: (extra, what needs it)
Need = tuple[str, str]


def _plot_facts(kw: dict[str, Any]) -> list[Need]:
    from toaster.outputs.plotting import IMAGE_FORMATS, output_format

    fmt = output_format(kw["output"], kw["fmt"])
    return [("plot", f"plot-facts to {fmt}")] if fmt in IMAGE_FORMATS else []


def _export(kw: dict[str, Any]) -> list[Need]:
    from toaster.outputs.export import export_format

    return (
        [("export", "export to parquet")]
        if export_format(kw["output"], kw["fmt"]) == "parquet"
        else []
    )


def _run(kw: dict[str, Any]) -> list[Need]:
    from toaster.app.runs import needed_extras

    return needed_extras(kw["path"], kw["record_dir"], kw["record_format"]) + _published("run", kw)


def _published(command: str, kw: dict[str, Any]) -> list[Need]:
    """The extras of the live outputs (cli/publish.py) that ``command`` is asked for."""
    return ([("ros2", f"toaster {command} --ros2")] if kw["ros2"] else []) + (
        [("foxglove", f"{command} --foxglove")] if kw["foxglove"] is not None else []
    )


#: command path (as typed after ``toaster``) -> the extras its arguments need
NEEDS: dict[str, Callable[[dict[str, Any]], list[Need]]] = {
    "plot-facts": _plot_facts,
    "export": _export,
    "record": lambda _kw: [("rosbag", "record")],
    "run": _run,
    "serve": lambda kw: _published("serve", kw),
}


def check_extras(path: str, kwargs: dict[str, Any]) -> None:
    """Raise the one-line :class:`~toaster.errors.MissingDependencyError` of the first extra
    that command ``path`` needs for ``kwargs`` and that is not installed."""
    needs = NEEDS.get(path)
    if needs is None:
        return
    from toaster.extras import require

    for extra, feature in needs(kwargs):
        require(extra, feature)
