"""The command-line reference (docs/cli.md), generated from the commands themselves.

``python -m toaster.cli.reference docs/cli.md`` writes it; ``tests/cli/test_contract.py``
fails when the file differs from what the commands say.
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from pathlib import Path

import click

#: help is laid out at this width, whatever the terminal (the file must not depend on it)
WIDTH = 100

HEADER = """\
# Command-line reference

Generated from the commands by `python -m toaster.cli.reference docs/cli.md`: do not edit by
hand (`tests/cli/test_contract.py` fails when it is out of date). The same text is
`toaster COMMAND --help`.

Rules every command follows:

- **`--db URL`** is accepted by every command, before or after its name
  (`toaster --db URL get-info AGENT` = `toaster get-info AGENT --db URL`). Precedence: the flag,
  else `$TOASTER_DB`, else `sqlite:///toaster.db` in the working directory. Two different
  `--db` on one line are refused.
- **Listings** (every command that prints rows) take `--limit N`, `--json` (JSON lines, every
  field, times in ns, ASCII) and `--csv` (every field, times in ns). On a terminal rows are a
  table; piped, the same columns are tab-separated lines under one header line (tabs, line
  breaks and other control characters in values escaped as `\\t`, `\\n`, `\\x1b`, a backslash
  doubled), and "no rows" goes to stderr. In CSV and tab-separated lines a text value starting
  with `=`, `+`, `-`, `@`, a tab, a line break or `'` gets one leading `'`, so that a
  spreadsheet reads no formula (docs/plotting.md). Tables show every key column of a row
  (agent, subject and its owner, property, sub-property, target and its owner); on a terminal
  an owner or sub-property column empty in every row is left out.
- **Optional extras** are checked before a command reads or writes anything: a missing one is
  one line naming `pip install 'toaster[EXTRA]'` (`plot` for pictures, `export` for Parquet,
  `rosbag` for bags and recordings).
- Bad input is one line naming the value and the fix (exit 1; usage errors exit 2); `--debug`
  shows the traceback.
"""


def commands(
    command: click.Command, ctx: click.Context
) -> Iterator[tuple[click.Command, click.Context]]:
    """``command`` and every subcommand below it (by name), each with its context."""
    yield command, ctx
    if isinstance(command, click.Group):
        for name in sorted(command.commands):
            sub = command.commands[name]
            if sub.hidden:
                continue
            yield from commands(
                sub,
                click.Context(
                    sub, info_name=name, parent=ctx, terminal_width=WIDTH, max_content_width=WIDTH
                ),
            )


def _anchor(path: str) -> str:
    return path.lower().replace(" ", "-")


def render() -> str:
    """The reference as Markdown: the rules, a contents list, each command's help."""
    from toaster.cli import cli

    root = click.Context(
        cli,
        info_name="toaster",
        terminal_width=WIDTH,
        max_content_width=WIDTH,
        **cli.context_settings,
    )
    found = list(commands(cli, root))
    lines = [HEADER, "## Contents", ""]
    for command, ctx in found:
        depth = ctx.command_path.count(" ")
        summary = command.get_short_help_str(limit=WIDTH)
        lines.append(
            f"{'  ' * depth}- [`{ctx.command_path}`](#{_anchor(ctx.command_path)})"
            + (f": {summary}" if depth else "")
        )
    for command, ctx in found:
        text = "\n".join(line.rstrip() for line in command.get_help(ctx).splitlines())
        lines += ["", f"## {ctx.command_path}", "", "```text", text, "```"]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> None:
    """Write the reference to the file given (default: print it)."""
    args = sys.argv[1:] if argv is None else argv
    text = render()
    if not args:
        sys.stdout.write(text)
        return
    Path(args[0]).write_text(text, encoding="utf-8")
    print(f"wrote {args[0]}", file=sys.stderr)


if __name__ == "__main__":
    main()
