"""Recordings of a run: rosbag2's MCAP layout, written and read without rosbag2.

A recording is an MCAP file as ``ros2 bag record -s mcap`` writes it: profile ``ros2``, one
channel per topic (message encoding ``cdr``, the publisher's QoS as ``offered_qos_profiles``),
one schema per type (encoding ``ros2msg``: the type's ``.msg`` text followed by every type it
nests, each after a line of ``=`` and ``MSG: pkg/Type`` — what rosbag2 stores), and each
message the CDR bytes exactly as they crossed DDS. So ``ros2 bag info``/``play``, Foxglove and
the ``mcap`` tools read it, and so does :func:`read` here.

Writing and summarising need only the ``mcap`` package; :func:`decode` turns a message back into
its ``ost_msgs`` dataclass through rclpy's deserialiser (imported when called).
"""

from __future__ import annotations

import importlib
import os
import re
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO

from ost_msgs_py.errors import InterfaceError

PRIMITIVES = frozenset(
    [
        "bool",
        "byte",
        "char",
        "float32",
        "float64",
        "int8",
        "uint8",
        "int16",
        "uint16",
        "int32",
        "uint32",
        "int64",
        "uint64",
        "string",
        "wstring",
    ]
)
SEPARATOR = "=" * 80


class BagError(InterfaceError):
    """A recording that cannot be written or read; the text names the file and the problem."""


# ----------------------------------------------------------------------------- definitions


def share_dirs() -> list[Path]:
    """Where interface definitions live: every ament prefix's ``share`` (the venv's first)."""
    prefixes = [sys.prefix, *os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep)]
    seen, out = set(), []
    for p in prefixes:
        d = Path(p) / "share"
        if p and d.is_dir() and d not in seen:
            seen.add(d)
            out.append(d)
    return out


def _msg_file(package: str, name: str) -> Path:
    for d in share_dirs():
        f = d / package / "msg" / f"{name}.msg"
        if f.is_file():
            return f
    raise BagError(f"no definition of {package}/msg/{name} under {[str(d) for d in share_dirs()]}")


def _nested(package: str, text: str) -> list[tuple[str, str]]:
    """The (package, name) of every non-primitive field type of a ``.msg`` text."""
    out = []
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        kind = line.split()[0]
        if "=" in line.split(None, 1)[-1].split()[0]:
            continue  # a constant (NAME=value)
        base = re.sub(r"\[.*\]$", "", kind)
        base = base.split("<=")[0]
        if base in PRIMITIVES:
            continue
        if "/" in base:
            parts = base.split("/")
            out.append((parts[0], parts[-1]))
        else:
            out.append((package, base))
    return out


def message_definition(type_name: str) -> str:
    """rosbag2's full text of a type (``pkg/msg/Name``): its ``.msg``, then each nested type once."""
    package, _, name = type_name.split("/")
    root = _msg_file(package, name).read_text()
    parts, done, todo = [root.rstrip("\n")], {(package, name)}, _nested(package, root)
    while todo:
        pkg, nm = todo.pop(0)
        if (pkg, nm) in done:
            continue
        done.add((pkg, nm))
        text = _msg_file(pkg, nm).read_text()
        parts.append(f"{SEPARATOR}\nMSG: {pkg}/{nm}\n{text.rstrip(chr(10))}")
        todo.extend(_nested(pkg, text))
    return "\n".join(parts) + "\n"


def qos_yaml(qos: Any) -> str:
    """A QoS profile as rosbag2 (Jazzy) stores it in ``offered_qos_profiles``."""
    if qos is None:
        return ""

    def name(policy: Any) -> str:
        return str(policy.name).lower()

    def dur(d: Any) -> str:
        ns = int(d.nanoseconds)
        if ns == 0:
            return "\n    sec: 2147483647\n    nsec: 4294967295"  # infinite, as rosbag2 writes it
        return f"\n    sec: {ns // 1_000_000_000}\n    nsec: {ns % 1_000_000_000}"

    return (
        f"- history: {name(qos.history)}\n"
        f"  depth: {int(qos.depth)}\n"
        f"  reliability: {name(qos.reliability)}\n"
        f"  durability: {name(qos.durability)}\n"
        f"  deadline:{dur(qos.deadline)}\n"
        f"  lifespan:{dur(qos.lifespan)}\n"
        f"  liveliness: {name(qos.liveliness)}\n"
        f"  liveliness_lease_duration:{dur(qos.liveliness_lease_duration)}\n"
        f"  avoid_ros_namespace_conventions: false\n"
    )


# ----------------------------------------------------------------------------- writing


class BagWriter:
    """Messages (CDR bytes) into an MCAP file in rosbag2's layout; schemas and channels are
    registered on first use. ``close()`` writes the summary (an unclosed file is still readable
    up to its last chunk by the mcap tools, but has no index)."""

    def __init__(self, path: str | Path, library: str = "ost watch_node"):
        from mcap.writer import CompressionType, Writer

        self.path = Path(path)
        try:
            self._file: BinaryIO = open(self.path, "wb")  # noqa: SIM115 - closed in close()
        except OSError as exc:
            raise BagError(f"{path}: cannot write ({exc.strerror})") from None
        self._writer = Writer(self._file, compression=CompressionType.ZSTD)
        self._writer.start(profile="ros2", library=library)
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self._seq: dict[int, int] = {}
        self.messages = 0
        self.closed = False

    def channel(self, topic: str, type_name: str, qos: Any = None) -> int:
        if topic in self._channels:
            return self._channels[topic]
        if type_name not in self._schemas:
            self._schemas[type_name] = self._writer.register_schema(
                name=type_name, encoding="ros2msg", data=message_definition(type_name).encode()
            )
        cid = self._writer.register_channel(
            topic=topic,
            message_encoding="cdr",
            schema_id=self._schemas[type_name],
            metadata={"offered_qos_profiles": qos_yaml(qos)},
        )
        self._channels[topic] = cid
        return cid

    def write(self, channel: int, data: bytes, log_time_ns: int, publish_time_ns: int | None = None) -> None:
        seq = self._seq.get(channel, 0)
        self._seq[channel] = seq + 1
        self._writer.add_message(
            channel_id=channel,
            log_time=log_time_ns,
            data=data,
            publish_time=log_time_ns if publish_time_ns is None else publish_time_ns,
            sequence=seq,
        )
        self.messages += 1

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        self._writer.finish()
        self._file.close()


# ----------------------------------------------------------------------------- reading


@dataclass(frozen=True)
class Recorded:
    topic: str
    type_name: str
    log_time_ns: int
    data: bytes


@dataclass(frozen=True)
class TopicInfo:
    topic: str
    type_name: str
    count: int
    qos: str


@dataclass(frozen=True)
class BagInfo:
    path: Path
    size: int
    profile: str
    library: str
    start_ns: int
    end_ns: int
    messages: int
    topics: tuple[TopicInfo, ...]

    @property
    def duration_s(self) -> float:
        return (self.end_ns - self.start_ns) / 1e9 if self.messages else 0.0

    def text(self) -> str:
        """As ``ros2 bag info`` prints it."""
        from datetime import UTC, datetime

        def stamp(ns: int) -> str:
            when = datetime.fromtimestamp(ns / 1e9, tz=UTC).strftime("%b %e %Y %H:%M:%S.%f")
            return f"{when[:-3]} ({ns / 1e9:.9f})"

        width = max((len(t.topic) for t in self.topics), default=0)
        lines = [
            f"Files:             {self.path.name}",
            f"Bag size:          {_size(self.size)}",
            "Storage id:        mcap",
            f"Duration:          {self.duration_s:.9f}s",
            f"Start:             {stamp(self.start_ns)}" if self.messages else "Start:             -",
            f"End:               {stamp(self.end_ns)}" if self.messages else "End:               -",
            f"Messages:          {self.messages}",
        ]
        for k, t in enumerate(self.topics):
            head = "Topic information: " if k == 0 else " " * 19
            lines.append(
                f"{head}Topic: {t.topic:<{width}} | Type: {t.type_name} | Count: {t.count} | "
                f"Serialization Format: cdr"
            )
        if not self.topics:
            lines.append("Topic information: ")
        return "\n".join(lines)


def _size(n: int) -> str:
    if n < 1024:
        return f"{n} B"
    value = float(n)
    for unit in ("KiB", "MiB"):
        value /= 1024
        if value < 1024:
            return f"{value:.1f} {unit}"
    return f"{value / 1024:.1f} GiB"


def _reader(f: BinaryIO, path: str | Path):
    from mcap.exceptions import McapError
    from mcap.reader import make_reader

    try:
        return make_reader(f)
    except (McapError, ValueError, EOFError) as exc:
        raise BagError(f"{path}: not an MCAP recording ({exc})") from None


def _open(path: str | Path) -> BinaryIO:
    try:
        return open(path, "rb")
    except FileNotFoundError:
        raise BagError(f"{path}: no such file") from None
    except OSError as exc:
        raise BagError(f"{path}: cannot read ({exc.strerror})") from None


def info(path: str | Path) -> BagInfo:
    """Topics, types, counts and time span of a recording (from its summary, or by a scan)."""
    from mcap.exceptions import McapError

    with _open(path) as f:
        reader = _reader(f, path)
        try:
            header = reader.get_header()
            summary = reader.get_summary()
            if summary is not None and summary.statistics is not None:
                st = summary.statistics
                counts, start, end, total = (
                    dict(st.channel_message_counts),
                    st.message_start_time,
                    st.message_end_time,
                    st.message_count,
                )
                channels, schemas = summary.channels, summary.schemas
            else:  # no summary (a recorder that did not close): count by reading
                counts, start, end, total, channels, schemas = {}, 0, 0, 0, {}, {}
                for schema, channel, message in reader.iter_messages():
                    channels[channel.id] = channel
                    if schema is not None:
                        schemas[schema.id] = schema
                    counts[channel.id] = counts.get(channel.id, 0) + 1
                    start = message.log_time if total == 0 else min(start, message.log_time)
                    end = max(end, message.log_time)
                    total += 1
        except (McapError, ValueError, EOFError, KeyError) as exc:
            raise BagError(f"{path}: damaged MCAP recording ({exc})") from None
    topics = tuple(
        TopicInfo(
            c.topic,
            schemas[c.schema_id].name if c.schema_id in schemas else "?",
            counts.get(cid, 0),
            c.metadata.get("offered_qos_profiles", ""),
        )
        for cid, c in sorted(channels.items(), key=lambda kv: kv[1].topic)
    )
    return BagInfo(
        Path(path), Path(path).stat().st_size, header.profile, header.library, start, end, total, topics
    )


def read(path: str | Path) -> Iterator[Recorded]:
    """Every message of a recording, in log-time order (undecoded)."""
    from mcap.exceptions import McapError

    with _open(path) as f:
        reader = _reader(f, path)
        try:
            for schema, channel, message in reader.iter_messages(log_time_order=True):
                yield Recorded(channel.topic, schema.name if schema else "", message.log_time, message.data)
        except (McapError, ValueError, EOFError) as exc:
            raise BagError(f"{path}: damaged MCAP recording ({exc})") from None


def ros_class(type_name: str) -> Any:
    """The generated Python class of ``pkg/msg/Name`` (rclpy's interface packages)."""
    package, _, name = type_name.split("/")
    try:
        return getattr(importlib.import_module(f"{package}.msg"), name)
    except (ImportError, AttributeError):
        raise BagError(f"unknown message type {type_name} (its interface package is not installed)") from None


def decode(rec: Recorded) -> Any:
    """A recorded message as its ROS message (rclpy's CDR deserialiser)."""
    return decode_bytes(rec.type_name, rec.data)


def decode_bytes(type_name: str, data: bytes) -> Any:
    """CDR bytes of ``pkg/msg/Name`` as its ROS message."""
    from rclpy.serialization import deserialize_message

    return deserialize_message(data, ros_class(type_name))
