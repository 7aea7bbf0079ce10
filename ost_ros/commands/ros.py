"""``ost ros``: a ros2cli stand-in on rclpy's graph API (ros2cli is not on PyPI).

    ost ros topic list [-t]          ost ros topic echo TOPIC [--once]
    ost ros topic hz TOPIC           ost ros node list

Output follows ``ros2 topic`` / ``ros2 node``. rclpy is imported inside the verbs, so the rest
of ``ost`` works without ROS. Like ``ros2 ... --no-daemon``, the graph is read after spinning
for ``--spin-time`` seconds (discovery takes 0–3 s).
"""

from __future__ import annotations

import argparse
import importlib
import math
import os
import time

from ost_ros.errors import UsageError


def _seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"invalid number {text!r}") from None
    if not 0 <= value <= 3600:
        raise argparse.ArgumentTypeError(f"must be in [0, 3600], got {value}")
    return value


def register(sub) -> None:
    from ost_ros.commands.args import OneLineParser

    ros = sub.add_parser(
        "ros",
        help="inspect a running ROS 2 graph (topics, nodes)",
        description="Inspect the ROS 2 graph like ros2cli: topic list/echo/hz, "
        "node list. Uses ROS_DOMAIN_ID from the environment.",
    )
    groups = ros.add_subparsers(dest="ros_verb", metavar="VERB", parser_class=OneLineParser)
    topic = groups.add_parser("topic", help="topics")
    tsub = topic.add_subparsers(dest="topic_verb", metavar="VERB", parser_class=OneLineParser)
    node = groups.add_parser("node", help="nodes")
    nsub = node.add_subparsers(dest="node_verb", metavar="VERB", parser_class=OneLineParser)

    def leaf(parent, name, func, spin_time=2.0, **kw):
        p = parent.add_parser(name, **kw)
        p.set_defaults(func=func, prog=p.prog)
        p.add_argument(
            "--spin-time",
            type=_seconds,
            default=spin_time,
            help=f"seconds to wait for discovery (default {spin_time:g}"
            + (": at most, until the topic has a publisher)" if spin_time > 2 else ")"),
        )
        return p

    p = leaf(tsub, "list", cmd_topic_list, help="output a list of available topics")
    p.add_argument("-t", "--show-types", action="store_true", help="also show the topic type")
    p = leaf(tsub, "echo", cmd_topic_echo, 10.0, help="output messages from a topic")
    p.add_argument("topic_name", help="name of the topic, e.g. /ost/result")
    p.add_argument("--once", action="store_true", help="print the first message received, then exit")
    p = leaf(tsub, "hz", cmd_topic_hz, 10.0, help="print the average publishing rate")
    p.add_argument("topic_name", help="name of the topic, e.g. /clock")
    p.add_argument("--window", "-w", type=int, default=10000, help="window size (messages)")
    leaf(nsub, "list", cmd_node_list, help="output a list of available nodes")


# ----------------------------------------------------------------------------- graph access


def _dds_defaults() -> None:
    """Talk DDS the way a run's nodes do (:func:`ost_ros.commands.bringup.dds_env`): UDP on
    loopback, via our Fast DDS profile, unless the user chose a profile of their own."""
    from ost_ros.commands.bringup import dds_env

    os.environ.update(dds_env())


class _Graph:
    """An rclpy context + node for the duration of a verb."""

    def __enter__(self):
        _dds_defaults()
        try:
            import rclpy
        except ImportError as exc:
            raise UsageError(f"rclpy is not available ({exc.name}); run bringup_scripts/setup.sh") from None
        self.rclpy = rclpy
        rclpy.init(args=[])
        self.node = rclpy.create_node("_ost_ros_cli", start_parameter_services=False, enable_rosout=False)
        return self

    def spin(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.rclpy.spin_once(self.node, timeout_sec=min(0.1, max(0.0, end - time.monotonic())))

    def topics(self) -> list[tuple[str, list[str]]]:
        return sorted(self.node.get_topic_names_and_types())

    def __exit__(self, exc_type, exc, tb):
        self.node.destroy_node()
        self.rclpy.try_shutdown()
        # SIGTERM/SIGINT shut the context down under a spinning verb: a normal way to stop it.
        return exc_type is not None and exc_type.__name__ == "ExternalShutdownException"


def _message_class(type_name: str):
    parts = type_name.split("/")
    if len(parts) != 3:
        raise UsageError(f"unsupported type name {type_name!r}")
    try:
        return getattr(importlib.import_module(f"{parts[0]}.{parts[1]}"), parts[2])
    except (ImportError, AttributeError):
        raise UsageError(f"message type {type_name} is not installed here") from None


def _wait_for_topic(g: _Graph, name: str, spin_time: float):
    end = time.monotonic() + max(spin_time, 0.1)
    while True:
        types = dict(g.topics()).get(name)
        if types and g.node.get_publishers_info_by_topic(name):
            return types[0]
        if time.monotonic() >= end:
            raise UsageError(f"topic {name} has no publisher (waited {spin_time:g} s; check ROS_DOMAIN_ID)")
        g.spin(0.1)


def _qos_for(g: _Graph, name: str):
    """Match the publishers, as ros2cli does: transient-local and reliable if they all offer it."""
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    infos = g.node.get_publishers_info_by_topic(name)
    reliable = all(i.qos_profile.reliability == ReliabilityPolicy.RELIABLE for i in infos)
    latched = all(i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in infos)
    return QoSProfile(
        depth=10,
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE,
    )


def _name(text: str) -> str:
    if not text.startswith("/"):
        text = "/" + text
    return text


# ----------------------------------------------------------------------------- message to YAML


def _yaml_scalar(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return "'" + v.replace("'", "''") + "'"
    return str(v)


def to_yaml(msg, indent: str = "") -> str:
    """ros2 topic echo's YAML rendering of a message (nested fields, sequences as '- ')."""
    lines = []
    for field in msg.get_fields_and_field_types():
        value = getattr(msg, field)
        if hasattr(value, "get_fields_and_field_types"):
            lines.append(f"{indent}{field}:")
            lines.append(to_yaml(value, indent + "  "))
        elif isinstance(value, (list, tuple)) or type(value).__name__ in ("ndarray", "array"):
            items = list(value)
            if not items:
                lines.append(f"{indent}{field}: []")
            elif hasattr(items[0], "get_fields_and_field_types"):
                lines.append(f"{indent}{field}:")
                for item in items:
                    body = to_yaml(item, indent + "  ").splitlines()
                    body[0] = indent + "- " + body[0][len(indent) + 2 :]
                    lines.extend(body)
            else:
                lines.append(f"{indent}{field}:")
                lines.extend(f"{indent}- {_yaml_scalar(x)}" for x in items)
        else:
            lines.append(f"{indent}{field}: {_yaml_scalar(value)}")
    return "\n".join(lines)


# ----------------------------------------------------------------------------- verbs


def cmd_topic_list(args: argparse.Namespace) -> int:
    with _Graph() as g:
        g.spin(args.spin_time)
        for name, types in g.topics():
            print(f"{name} [{', '.join(types)}]" if args.show_types else name)
    return 0


def cmd_node_list(args: argparse.Namespace) -> int:
    with _Graph() as g:
        g.spin(args.spin_time)
        names = set()
        for name, ns in g.node.get_node_names_and_namespaces():
            if name == "_ost_ros_cli":
                continue
            names.add(ns.rstrip("/") + "/" + name)
        for n in sorted(names):
            print(n)
    return 0


def cmd_topic_echo(args: argparse.Namespace) -> int:
    name = _name(args.topic_name)
    with _Graph() as g:
        cls = _message_class(_wait_for_topic(g, name, args.spin_time))
        seen = []

        def show(msg):
            seen.append(1)
            print(to_yaml(msg))
            print("---", flush=True)

        g.node.create_subscription(cls, name, show, _qos_for(g, name))
        while not (args.once and seen):
            g.rclpy.spin_once(g.node, timeout_sec=0.1)
    return 0


def cmd_topic_hz(args: argparse.Namespace) -> int:
    name = _name(args.topic_name)
    with _Graph() as g:
        cls = _message_class(_wait_for_topic(g, name, args.spin_time))
        stamps: list[float] = []
        g.node.create_subscription(cls, name, lambda _m: stamps.append(time.monotonic()), _qos_for(g, name))
        next_print = time.monotonic() + 1.0
        while True:
            g.rclpy.spin_once(g.node, timeout_sec=0.1)
            if time.monotonic() < next_print:
                continue
            next_print += 1.0
            del stamps[: -args.window - 1]
            if len(stamps) < 2:
                continue
            gaps = [b - a for a, b in zip(stamps, stamps[1:])]
            mean = sum(gaps) / len(gaps)
            std = math.sqrt(sum((x - mean) ** 2 for x in gaps) / len(gaps))
            print(
                f"average rate: {1.0 / mean:.3f}\n\tmin: {min(gaps):.3f}s max: {max(gaps):.3f}s "
                f"std dev: {std:.5f}s window: {len(stamps)}",
                flush=True,
            )
