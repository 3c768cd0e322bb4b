"""README.md runs: every command of its ```bash blocks and every ```python block, in order, in
a fresh directory.

Commands run one by one through ``bash -c`` (python blocks through the venv's interpreter)
in a temporary directory holding what a fresh clone has at the paths the README names
(``src/toaster/examples``), with the venv's ``toaster`` first on PATH; an ``export NAME=VALUE`` line sets NAME for the commands after it.
A command whose trailing comment starts with ``needs`` (``# needs ROS 1``) is not run: it
needs what a test machine lacks. The first block's install steps are what this test
environment already did, and its ``python -m pytest -q`` is this suite.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path
from typing import NamedTuple

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
LEAD = [
    "python3 -m venv .venv && . .venv/bin/activate && pip install -e '.[test]' && toaster demo",
    "python -m pytest -q",
]
#: Steps of the lead block this environment has already done (the venv, the install) or is
#: doing (the tests).
DONE = {
    "python3 -m venv .venv",
    ". .venv/bin/activate",
    "pip install -e '.[test]'",
    "python -m pytest -q",
}
NEEDS = re.compile(r"\s#\s*needs\b[^'\"]*$")
EXPORT = re.compile(r"export ([A-Z_][A-Z0-9_]*)=(\S+)$")
COPIED = ("src/toaster/examples",)  # what README commands read from the clone
TIMEOUT_S = 300


class Command(NamedTuple):
    line: int  # README line number
    text: str
    lang: str = "bash"  # or "python": the whole block, run as one script


def code_blocks(text: str) -> list[list[Command]]:
    """The commands of each ```bash block (continued lines joined, comment lines dropped) and
    each ```python block (one command: the block), in README order."""
    blocks: list[list[Command]] = []
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        lang = lines[i].strip().removeprefix("```")
        if not lines[i].strip().startswith("```") or lang not in ("bash", "python"):
            i += 1
            continue
        first, body = i + 2, []
        i += 1
        while lines[i].strip() != "```":
            body.append(lines[i])
            i += 1
        i += 1
        if lang == "python":
            blocks.append([Command(first, "\n".join(body) + "\n", "python")])
        else:
            blocks.append(bash_commands(body, first))
    return blocks


def bash_commands(body: list[str], first: int) -> list[Command]:
    """One command per line, lines ending with a backslash continued."""
    commands, j = [], 0
    while j < len(body):
        start, parts = first + j, [body[j]]
        while parts[-1].endswith("\\"):
            j += 1
            parts[-1] = parts[-1][:-1]
            parts.append(body[j])
        command = " ".join(p.strip() for p in parts).strip()
        if command and not command.startswith("#"):
            commands.append(Command(start, command))
        j += 1
    return commands


def run(command: Command, cwd: Path, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    """A bash command through ``bash -c``, a python block through the venv's interpreter."""
    argv = (
        [sys.executable, "-c", command.text]
        if command.lang == "python"
        else ["bash", "-c", command.text]
    )
    return subprocess.run(
        argv, cwd=cwd, env=env, capture_output=True, text=True, timeout=TIMEOUT_S, check=False
    )


def test_readme_leads_with_the_two_commands() -> None:
    """Install + demo, then the tests: the README's first block, as written."""
    first = code_blocks(README.read_text(encoding="utf-8"))[0]
    assert [c.text for c in first] == LEAD


@pytest.mark.slow
def test_readme_commands_run(tmp_path: Path) -> None:
    """Every README command succeeds, in the order shown, in a fresh directory."""
    for name in COPIED:
        shutil.copytree(ROOT / name, tmp_path / name)
    env = {k: v for k, v in os.environ.items() if not k.startswith("TOASTER_")}
    for key in ("TOASTER_TEST_POSTGRES_URL", "TOASTER_REQUIRE_POSTGRES"):
        if key in os.environ:
            env[key] = os.environ[key]
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    failures, ran = [], 0
    for block in code_blocks(README.read_text(encoding="utf-8")):
        for command in block:
            if command.lang == "bash":
                if NEEDS.search(command.text):
                    continue
                steps = [s for s in command.text.split(" && ") if s.strip() not in DONE]
                if not steps:
                    continue
                export = EXPORT.match(" && ".join(steps))
                if export is not None:
                    env[export[1]] = shlex.split(export[2])[0]
                    continue
                command = command._replace(text=" && ".join(steps))
            done = run(command, tmp_path, env)
            ran += 1
            if done.returncode != 0:
                said = (done.stderr.strip() or done.stdout.strip()).splitlines()[-3:]
                failures.append(
                    f"README.md:{command.line}: {command.text.strip()}\n    exit "
                    f"{done.returncode}: " + "\n    ".join(said)
                )
    assert ran >= 20, f"only {ran} README commands found: is the parser still right?"
    if failures:
        pytest.fail(
            f"{len(failures)} of {ran} README commands failed:\n" + "\n".join(failures),
            pytrace=False,
        )
