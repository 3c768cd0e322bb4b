"""`import toaster` (and `toaster.beliefs`, `toaster.db`): every name listed, resolving, typed,
and loaded lazily so that importing toaster or running `toaster --help` stays cheap."""

from __future__ import annotations

import ast
import importlib
import re
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import pytest

import toaster

ROOT = Path(__file__).resolve().parents[1]
LAZY_PACKAGES = ["toaster", "toaster.beliefs", "toaster.db", "toaster.producers"]
#: what `import toaster` and `toaster --help` must not load (seconds of import time)
HEAVY = (
    "sqlalchemy",
    "alembic",
    "psycopg",
    "numpy",
    "scipy",
    "shapely",
    "matplotlib",
    "pandas",
    "pyarrow",
    "rosbags",
    "cyclonedds",
    "foxglove",
)


def loaded_after(code: str) -> set[str]:
    """The heavy packages a fresh interpreter has imported after running ``code``."""
    probe = (
        f"{code}\nimport sys\n"
        f"print(' '.join(m for m in {HEAVY!r} if m in sys.modules), file=sys.stderr)"
    )
    done = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, check=True, timeout=120
    )
    return set(done.stderr.split())


@pytest.mark.parametrize("package", LAZY_PACKAGES)
def test_importing_a_package_loads_nothing_heavy(package: str) -> None:
    assert loaded_after(f"import {package}") == set()


def test_toaster_help_loads_nothing_heavy() -> None:
    code = (
        "import sys\nfrom toaster.cli import main\nsys.argv = ['toaster', '--help']\n"
        "try:\n    main()\nexcept SystemExit as exc:\n    assert exc.code in (0, None)"
    )
    assert loaded_after(code) == set()


@pytest.mark.parametrize("package", LAZY_PACKAGES)
def test_every_export_is_listed_and_resolves(package: str) -> None:
    module = importlib.import_module(package)
    assert module.__all__, package
    listed = dir(module)
    for name in module.__all__:
        assert name in listed, f"dir({package}) misses {name}"
        value = getattr(module, name)
        assert value is not None
        if isinstance(value, ModuleType):
            assert value.__name__ == f"{package}.{name}"
        else:  # the object its home module defines, not a copy
            assert getattr(importlib.import_module(module._HOMES[name]), name) is value
    star: dict[str, object] = {}
    exec(f"from {package} import *", star)
    assert set(module.__all__) <= star.keys()


@pytest.mark.parametrize("package", LAZY_PACKAGES)
def test_a_misspelt_name_is_an_attribute_error_naming_it(package: str) -> None:
    module = importlib.import_module(package)
    with pytest.raises(
        AttributeError,
        match=rf"module '{re.escape(package)}' has no attribute "
        "'conect'",
    ):
        _ = module.conect
    assert not hasattr(module, "conect")


def _declared(package: str) -> tuple[set[str], set[str], bool]:
    """(names imported under ``if TYPE_CHECKING:``, keys of ``_HOMES``, whether
    ``__getattr__`` is hidden from type checkers) from the package's source."""
    path = Path(importlib.import_module(package).__file__ or "")
    typed: set[str] = set()
    homes: set[str] = set()
    hidden = False
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.If):
            test = ast.unparse(node.test)
            if test == "TYPE_CHECKING":
                typed |= {
                    a.asname or a.name
                    for n in node.body
                    if isinstance(n, ast.ImportFrom)
                    for a in n.names
                }
            elif test == "not TYPE_CHECKING":
                hidden = "__getattr__" in ast.unparse(node)
        elif isinstance(node, ast.Assign) and ast.unparse(node.targets[0]) == "_HOMES":
            assert isinstance(node.value, ast.Dict)
            homes = {ast.literal_eval(k) for k in node.value.keys if k is not None}
    return typed, homes, hidden


@pytest.mark.parametrize("package", LAZY_PACKAGES)
def test_type_checkers_see_every_lazy_name(package: str) -> None:
    """A lazy name without its TYPE_CHECKING import would be invisible (or Any) to mypy."""
    typed, homes, hidden = _declared(package)
    assert typed == homes == set(importlib.import_module(package).__all__)
    assert hidden, f"{package}.__getattr__ must be defined under `if not TYPE_CHECKING:`"


@pytest.mark.slow
def test_mypy_gives_the_front_door_real_types(tmp_path: Path) -> None:
    """Through mypy (the project's config and cache): no export is Any, a typo is an error."""
    mypy_api = pytest.importorskip("mypy.api")
    names = [f"{p}.{n}" for p in LAZY_PACKAGES for n in importlib.import_module(p).__all__]
    probe = tmp_path / "probe.py"
    probe.write_text(
        "".join(f"import {p}\n" for p in LAZY_PACKAGES)
        + "".join(f"reveal_type({n})\n" for n in names)
        + "toaster.conect\ntoaster.beliefs.belief\n",
        encoding="utf-8",
    )
    with pytest.MonkeyPatch.context() as mp:
        mp.chdir(ROOT)
        out, err, _ = mypy_api.run(["--no-error-summary", str(probe)])
    revealed = re.findall(r'Revealed type is "(.*)"', out)
    assert len(revealed) == len(names), out + err
    untyped = [n for n, t in zip(names, revealed, strict=False) if t == "Any"]
    assert not untyped, f"type checkers see these as Any: {untyped}"
    assert len(re.findall(r'has no attribute "(conect|belief)"', out)) == 2, out


@pytest.mark.slow
def test_architecture_example_runs(
    db_url: str, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The Python example of docs/architecture.md prints what it says, on each backend."""
    page = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    code = re.search(r"```python\n(.*?)```", page, re.DOTALL)
    assert code is not None
    example = code.group(1)
    assert example.count('"sqlite:///toaster.db"') == 1
    monkeypatch.chdir(ROOT)  # the example names the scenario from the repository's root
    scope: dict[str, object] = {}
    exec(example.replace('"sqlite:///toaster.db"', repr(db_url)), scope)
    db = scope["db"]
    assert isinstance(db, toaster.Database)
    try:
        printed = capsys.readouterr().out.splitlines()
        promised = [
            line.removeprefix("# ") for line in example.splitlines() if line.startswith("# MARBLE")
        ]
        assert (
            printed
            == promised
            == [
                "MARBLE IsIn BASKET Sally: true robot: None",
                "MARBLE IsIn BOX Sally: None robot: true",
            ]
        )
        told = toaster.belief_value(db, "SALLY", "MARBLE", "IsIn", "BASKET")
        assert told is not None and told.source == "told:ANNE"
        # a told place replaces the one she believed: the lie is now her false belief
        assert [
            (d.target_id, d.value_a, d.value_b) for d in toaster.false_beliefs(db, "SALLY")
        ] == [("BASKET", "true", None), ("BOX", None, "true")]
    finally:
        db.close()


@pytest.mark.slow
def test_tell_is_the_function_whichever_import_runs_first() -> None:
    code = (
        "import toaster.beliefs.tell, toaster\n"
        "assert callable(toaster.tell) and toaster.tell.__module__ == 'toaster.beliefs.tell'"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)
