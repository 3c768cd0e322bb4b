"""The message packages Debian's ROS tools need to decode toaster (``toaster ros1 env``).

``rostopic``, ``rosservice`` and ``rosbag`` find a message type ``pkg/Name`` as the Python
module ``pkg.msg`` (on ``PYTHONPATH``), ``rosmsg``/``rossrv`` its definition as
``<pkg>/msg/Name.msg`` in a package on ``ROS_PACKAGE_PATH``. :func:`package_tree` makes both
for each package toaster speaks (those shipped in ``msgs/``: toaster_msgs, hri_msgs, std_srvs;
and the recordings' toaster_recording) whose Python module Debian does not install: Debian's
``python3-std-srvs``, when installed, is used, not shadowed by toaster's one-service copy.

    <cache>/<toaster version>-<digest>/share/<pkg>/{package.xml, msg/, srv/}
    <cache>/<toaster version>-<digest>/python/<pkg>/{__init__.py, msg/, srv/}

The digest covers the definitions and the package choice, so a changed ``.msg`` or a newly
installed Debian package gives a new tree. The modules are written once by Debian's genpy
under Debian's Python (``gentree.py``), the interpreter the ROS tools run, whatever Python
toaster runs in; a tree is built in a temporary folder and renamed into place, so concurrent
calls never see half a tree.
"""

from __future__ import annotations

import hashlib
import os
import shlex
import shutil
import subprocess
import tempfile
import time
from collections.abc import Mapping
from importlib import metadata
from pathlib import Path

from toaster.errors import InvalidInputError
from toaster.ros1.available import RosUnavailableError
from toaster.ros1.gentree import MISSING
from toaster.ros1.messages import DEBIAN_DIST, MSG_ROOT

SYSTEM_PYTHON = "/usr/bin/python3"
GENERATOR = Path(__file__).with_name("gentree.py")
#: bumped when the tree's layout changes (older trees are then left unused)
LAYOUT = "1"
TOOLS_HINT = (
    "ROS 1's tools are not installed: apt-get install --no-install-recommends ros-core "
    "python3-genpy python3-genmsg python3-std-msgs python3-geometry-msgs"
)
PACKAGE_XML = """\
<?xml version="1.0"?>
<package format="2">
  <name>{name}</name>
  <version>{version}</version>
  <description>{name} as toaster speaks it (written by `toaster ros1 env`)</description>
  <maintainer email="toaster@example.org">toaster</maintainer>
  <license>BSD</license>
  <buildtool_depend>catkin</buildtool_depend>
</package>
"""


def toaster_version() -> str:
    """The installed toaster's version ("0" when it runs from a source tree only)."""
    try:
        return metadata.version("toaster")
    except metadata.PackageNotFoundError:
        return "0"


def default_cache(environ: Mapping[str, str] = os.environ) -> Path:
    """``$XDG_CACHE_HOME/toaster/ros1`` (``~/.cache`` when unset)."""
    base = environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "toaster" / "ros1"


def definitions(root: Path = MSG_ROOT) -> dict[str, dict[str, str]]:
    """Message and service texts by package and path in it (``{"toaster_msgs": {"msg/Fact.msg":
    text}}``): those shipped under ``root`` and the recordings' own ``toaster_recording``
    types (:data:`toaster.outputs.recording.OWN_MESSAGES`)."""
    from toaster.outputs.recording import OWN_MESSAGES

    out: dict[str, dict[str, str]] = {}
    for path in sorted(root.glob("*/*/*.*")):
        if path.parent.name in ("msg", "srv") and path.suffix == f".{path.parent.name}":
            package = path.parents[1].name
            out.setdefault(package, {})[f"{path.parent.name}/{path.name}"] = path.read_text()
    for type_name, text in OWN_MESSAGES.items():
        package, kind, name = type_name.split("/")
        out.setdefault(package, {})[f"{kind}/{name}.{kind}"] = text
    return out


def tree_packages(
    texts: Mapping[str, Mapping[str, str]], dist: str | Path = DEBIAN_DIST
) -> dict[str, Mapping[str, str]]:
    """The packages of ``texts`` whose Python module Debian (``dist``) does not install."""
    return {name: files for name, files in texts.items() if not (Path(dist) / name).is_dir()}


def tree_name(packages: Mapping[str, Mapping[str, str]]) -> str:
    """``<toaster version>-<digest>``: the digest covers the layout and every package's
    definitions."""
    digest = hashlib.sha256(f"layout {LAYOUT}\n".encode())
    for name in sorted(packages):
        for path, text in sorted(packages[name].items()):
            digest.update(f"{name}/{path} {len(text.encode())}\n{text}".encode())
    return f"{toaster_version()}-{digest.hexdigest()[:16]}"


def _write_share(share: Path, packages: Mapping[str, Mapping[str, str]]) -> None:
    """``share/<pkg>/{package.xml, msg/, srv/}``: the definitions as shipped."""
    for name, files in packages.items():
        for path, text in files.items():
            (share / name / path).parent.mkdir(parents=True, exist_ok=True)
            (share / name / path).write_text(text)
        (share / name / "package.xml").write_text(
            PACKAGE_XML.format(name=name, version=toaster_version())
        )


def _generate(share: Path, out: Path, python: str, cache: Path) -> None:
    """The Python modules of ``share``'s packages, by Debian's genpy under ``python``."""
    done = subprocess.run(
        [python, str(GENERATOR), str(share), str(out)],
        capture_output=True,
        text=True,
        check=False,
        env=dict(os.environ) | {"PYTHONPATH": _without(os.environ.get("PYTHONPATH"), cache)},
    )
    if done.returncode == 0:
        return
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    last = lines[-1].strip() if lines else f"exit status {done.returncode}"
    if done.returncode == MISSING:
        msg = f"{TOOLS_HINT} ({last})"
        raise RosUnavailableError(msg)
    msg = f"genpy could not generate toaster's messages: {last}"
    raise RosUnavailableError(msg)


def package_tree(
    cache: Path | None = None, *, root: Path = MSG_ROOT, python: str | None = None
) -> Path:
    """The tree of the packages in ``cache`` (:func:`default_cache`), generated on first use by
    ``python`` (:data:`SYSTEM_PYTHON`). Concurrent callers each build in a temporary folder;
    the first rename wins and the others use its tree."""
    cache = (default_cache() if cache is None else cache).absolute()
    python = python or SYSTEM_PYTHON
    if not Path(python).is_file():
        msg = f"{TOOLS_HINT} ({python} is missing)"
        raise RosUnavailableError(msg)
    packages = tree_packages(definitions(root))
    final = cache / tree_name(packages)
    if final.is_dir():
        return final
    try:
        cache.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{final.name}.", dir=cache))
    except OSError as exc:
        msg = f"cannot write the message packages in {cache} ({exc.strerror}): give --cache DIR"
        raise InvalidInputError(msg) from None
    try:
        _write_share(tmp / "share", packages)
        (tmp / "python").mkdir()
        _generate(tmp / "share", tmp / "python", python, cache)
        try:
            tmp.rename(final)
        except OSError:
            if not final.is_dir():  # not "another caller was first"
                raise
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    _sweep(cache)
    return final


def _sweep(cache: Path, age_s: float = 3600.0) -> None:
    """Remove the temporary folders of builds that were killed (older than ``age_s``)."""
    now = time.time()
    for tmp in cache.glob(".*"):
        try:
            if tmp.is_dir() and now - tmp.stat().st_mtime > age_s:
                shutil.rmtree(tmp, ignore_errors=True)
        except OSError:  # another caller removed it first
            continue


def _without(current: str | None, cache: Path) -> str:
    """A search path (``a:b``) without the entries inside ``cache``."""
    ours = str(cache) + os.sep
    kept = [p for p in (current or "").split(os.pathsep) if p and not p.startswith(ours)]
    return os.pathsep.join(kept)


def _prepend(entry: Path, current: str | None, cache: Path) -> str:
    """``entry`` before ``current``'s entries, without the trees an earlier call put there
    (evaluating the exports twice does not grow the variable)."""
    rest = _without(current, cache)
    return f"{entry}{os.pathsep}{rest}" if rest else str(entry)


def ros_environment(
    tree: Path, cache: Path, environ: Mapping[str, str] = os.environ
) -> dict[str, str]:
    """``ROS_PACKAGE_PATH`` and ``PYTHONPATH`` with ``tree`` put first."""
    return {
        "ROS_PACKAGE_PATH": _prepend(tree / "share", environ.get("ROS_PACKAGE_PATH"), cache),
        "PYTHONPATH": _prepend(tree / "python", environ.get("PYTHONPATH"), cache),
    }


def exports(values: Mapping[str, str]) -> str:
    """``export NAME=value`` lines for a POSIX shell, values quoted."""
    return "".join(f"export {name}={shlex.quote(value)}\n" for name, value in values.items())
