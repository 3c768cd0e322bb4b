"""The DDS side of the ROS 2 bridge: a participant, QoS as ROS 2's profiles, typed readers and
writers on ROS 2 topic names (:mod:`toaster.ros2.names`)."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from toaster.ros2 import names
from toaster.ros2.idl import Types

#: keep-last depths: rclcpp's default profile (10), tf2's /tf listener (100), latched lists (1)
DEPTH, TF_DEPTH = 10, 100
#: how long a writer's "has a reader" answer is kept (a new reader waits at most this long)
MATCH_EVERY_S = 0.5
#: samples taken per call when a reader's data comes
TAKE_N = 256


def raw_calls() -> tuple[Callable[[int, bytes], int], Callable[[int, int, int], Any]]:
    """cyclonedds' ``_clayer.ddspy_write(ref, cdr)`` and ``ddspy_take(ref, mask, n)`` (a list
    of (cdr bytes, sample info)): what its DataWriter.write and DataReader.take call around
    its Python codec, which is ~10x slower than :mod:`toaster.ros2.cdr` on the messages of a
    tick. They are private to the binding (checked for 11.0, pinned ``<12`` in pyproject):
    if a release renames or changes them, the bridge fails here, at start, in one line, and
    ``tests/ros2/test_wire.py::test_the_binding_s_raw_calls`` fails."""
    try:
        from cyclonedds import _clayer  # type: ignore[attr-defined]

        write, take = _clayer.ddspy_write, _clayer.ddspy_take
    except (ImportError, AttributeError) as exc:
        from importlib.metadata import version

        from toaster.errors import ToasterError

        found = version("cyclonedds")
        msg = f"cyclonedds {found} lacks the private calls toaster.ros2.dds uses ({exc}): "
        msg += "pip install 'cyclonedds>=11.0,<12'"
        raise ToasterError(msg) from exc
    return write, take


def qos(kind: str, depth: int = DEPTH) -> Any:
    """A ROS 2 QoS profile: ``reliable`` (rmw_qos_profile_default), ``sensor``
    (rmw_qos_profile_sensor_data: best effort), ``latched`` (reliable, transient local, as
    /tf_static and ``ros2 topic pub --qos-durability transient_local``), or ``reader``
    (reliable, and ignoring member names: ROS 2's rmw match on the type name)."""
    from cyclonedds.core import Policy, Qos
    from cyclonedds.util import duration

    reliability = (
        Policy.Reliability.BestEffort
        if kind == "sensor"
        else Policy.Reliability.Reliable(max_blocking_time=duration(milliseconds=100))
    )
    durability = (
        Policy.Durability.TransientLocal if kind == "latched" else Policy.Durability.Volatile
    )
    return Qos(reliability, durability, Policy.History.KeepLast(depth))


def reader_qos(kind: str, depth: int = DEPTH, *, ignore_own: bool = False) -> Any:
    """A reader's QoS: ``kind`` as :func:`qos` (a best-effort reader matches both kinds of
    writer), member names not compared (a ROS 2 type is matched by its name and layout)."""
    from cyclonedds.core import Policy, Qos

    extra: list[Any] = [
        Policy.TypeConsistency.AllowTypeCoercion(
            ignore_sequence_bounds=True, ignore_string_bounds=True, ignore_member_names=True
        )
    ]
    if ignore_own:
        extra.append(Policy.IgnoreLocal.Participant)
    return Qos(*qos(kind, depth).policies, *extra)


#: :func:`raw_calls`, once a participant was made
_RAW: list[Any] = []


class Dds:
    """One DDS participant on a domain, with readers and writers of ROS 2 topics."""

    def __init__(self, domain: int, types: Types) -> None:
        from cyclonedds.domain import DomainParticipant

        if not _RAW:
            _RAW.extend(raw_calls())
        self.domain, self.types = domain, types
        self.participant: Any = DomainParticipant(domain)
        self._topics: dict[str, Any] = {}
        self.readers: list[Any] = []
        self.writers: list[Any] = []
        self._matched: dict[int, tuple[float, bool]] = {}

    def topic(self, dds_name: str, cls: Any) -> Any:
        from cyclonedds.topic import Topic

        if dds_name not in self._topics:
            self._topics[dds_name] = Topic(self.participant, dds_name, cls)
        return self._topics[dds_name]

    def writer(
        self, ros_topic: str, msgtype: str, kind: str = "reliable", depth: int = DEPTH
    ) -> Any:
        """A writer of ``msgtype`` on ROS 2 topic ``ros_topic``."""
        return self.raw_writer(names.topic(ros_topic), self.types.cls(msgtype), qos(kind, depth))

    def raw_writer(self, dds_name: str, cls: Any, profile: Any) -> Any:
        from cyclonedds.pub import DataWriter

        writer = DataWriter(self.participant, self.topic(dds_name, cls), qos=profile)
        self.writers.append(writer)
        return writer

    def reader(
        self,
        ros_topic: str,
        msgtype: str,
        on_sample: Callable[[Any], None],
        kind: str = "sensor",
        depth: int = DEPTH,
        *,
        ignore_own: bool = False,
        raw: bool = False,
    ) -> Any:
        """A reader of ``msgtype`` on ROS 2 topic ``ros_topic``; ``on_sample`` runs on
        cyclonedds' receive thread for each sample (its CDR bytes when ``raw``)."""
        profile = reader_qos(kind, depth, ignore_own=ignore_own)
        cls = self.types.cls(msgtype)
        return self.raw_reader(names.topic(ros_topic), cls, profile, on_sample, raw=raw)

    def raw_reader(
        self,
        dds_name: str,
        cls: Any,
        profile: Any,
        on_sample: Callable[[Any], None],
        *,
        raw: bool = False,
    ) -> Any:
        """A reader of DDS topic ``dds_name``; ``on_sample`` gets each sample, as CDR bytes
        when ``raw`` (:mod:`toaster.ros2.cdr` reads them faster than cyclonedds' codec)."""
        from cyclonedds.core import Listener
        from cyclonedds.sub import DataReader

        def available(reader: Any) -> None:
            if raw:
                for data in self.take_raw(reader):
                    on_sample(data)
                return
            for sample in reader.take(N=TAKE_N):
                if getattr(sample, "sample_info", None) is None or sample.sample_info.valid_data:
                    on_sample(sample)

        reader = DataReader(
            self.participant,
            self.topic(dds_name, cls),
            qos=profile,
            listener=Listener(on_data_available=available),
        )
        self.readers.append(reader)
        return reader

    @staticmethod
    def write_raw(writer: Any, data: bytes) -> None:
        """Write a sample's CDR bytes as they are (cyclonedds checks them against the type)."""
        ret = _RAW[0](writer._ref, data)
        if ret < 0:
            msg = f"DDS write of {len(data)} bytes failed (code {ret})"
            raise OSError(msg)

    @staticmethod
    def take_raw(reader: Any, n: int = TAKE_N) -> list[bytes]:
        """Take up to ``n`` samples of ``reader`` as CDR bytes (samples without data, as a
        disposed instance's, are left out)."""
        from cyclonedds.core import InstanceState, SampleState, ViewState

        mask = SampleState.Any | ViewState.Any | InstanceState.Any
        taken = _RAW[1](reader._ref, mask, n)
        if isinstance(taken, int):  # a DDS error code, as DataReader.take raises it
            msg = f"DDS take failed (code {taken})"
            raise OSError(msg)
        return [data for data, info in taken if info.valid_data]

    def listened(self, writer: Any) -> bool:
        """Whether a reader is matched to ``writer`` (nothing is built for nobody), asked of
        DDS at most every :data:`MATCH_EVERY_S` per writer (a call into cyclonedds each time;
        it keeps the interpreter, docs/ros2.md "Latency")."""
        now = time.monotonic()
        known = self._matched.get(id(writer))
        if known is None or now >= known[0]:
            count = writer.get_publication_matched_status().current_count
            known = self._matched[id(writer)] = (now + MATCH_EVERY_S, bool(count))
        return known[1]

    def close(self) -> None:
        """Delete the participant and everything in it."""
        from cyclonedds.core import Listener

        for reader in self.readers:
            reader.set_listener(Listener())
        self.readers, self.writers, self._topics = [], [], {}
        participant, self.participant = self.participant, None
        del participant
