"""Python modules of ROS 1 message packages, written by Debian's genpy as catkin's build does.

``/usr/bin/python3 gentree.py SHARE OUT`` reads every package ``SHARE/<name>/`` (a
``package.xml``, ``msg/*.msg``, ``srv/*.srv``) and writes ``OUT/<name>/`` with ``msg/`` and
``srv/`` modules (genpy's ``MsgGenerator`` / ``SrvGenerator``, ``__init__.py`` by
``generate_initpy``), the layout ``rostopic``, ``rosservice`` and ``rosbag`` import. The
standard types the messages use (``std_msgs/Header``, ``geometry_msgs/Pose``...) are read
from Debian's generated classes (:func:`messages.standard_texts`), so Debian's ``.msg``
definition packages are not needed.

Run by file path under Debian's Python (which has no toaster): it imports nothing from
toaster, only its sibling :mod:`messages` (itself toaster-free) by path. Exit status 2 with
one line on stderr when genpy (or a standard message package) cannot be
imported, 1 when a definition does not generate.
"""

from __future__ import annotations

import importlib.util
import sys
import tempfile
from pathlib import Path
from types import ModuleType

MISSING = 2
FAILED = 1


def _messages() -> ModuleType:
    """The sibling ``messages.py``, loaded by path (this file is not run as a package)."""
    spec = importlib.util.spec_from_file_location(
        "toaster_ros1_messages", Path(__file__).with_name("messages.py")
    )
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def generate(share: Path, out: Path) -> None:
    """Write the Python modules of every package under ``share`` into ``out``."""
    messages = _messages()
    messages.ros_path()
    from genpy.generate_initpy import write_modules  # type: ignore[import-not-found]
    from genpy.generator import MsgGenerator, SrvGenerator  # type: ignore[import-not-found]

    packages = sorted(p for p in share.iterdir() if (p / "package.xml").is_file())
    with tempfile.TemporaryDirectory() as deps:
        search: dict[str, list[str]] = {}
        for full, text in messages.standard_texts().items():
            package, name = full.split("/")
            folder = Path(deps, package, "msg")
            folder.mkdir(parents=True, exist_ok=True)
            (folder / f"{name}.msg").write_text(text)
            search[package] = [str(folder)]
        for package in packages:
            search.setdefault(package.name, []).insert(0, str(package / "msg"))
        for package in packages:
            (out / package.name).mkdir(parents=True)
            (out / package.name / "__init__.py").write_text("")
            for kind, generator in (("msg", MsgGenerator()), ("srv", SrvGenerator())):
                files = [str(f) for f in sorted((package / kind).glob(f"*.{kind}"))]
                if not files:
                    continue
                target = str(out / package.name / kind)
                if generator.generate_messages(package.name, files, target, search):
                    raise SystemExit(FAILED)  # genpy printed which file and why
                write_modules(target)


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print("usage: python3 gentree.py SHARE OUT", file=sys.stderr)
        return FAILED
    try:
        generate(Path(argv[0]), Path(argv[1]))
    except ImportError as exc:  # genpy, genmsg, std_msgs or geometry_msgs
        print(f"{sys.executable} cannot import {exc.name} ({exc})", file=sys.stderr)
        return MISSING
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
