"""Fuzzing what a node does with a received message (hypothesis): random and edge-case fields of
every interface — huge arrays, extreme and negative ids, unknown enum values, odd strings,
random tags — serialised by rclpy, and now and then cut short or with bytes flipped, through the
receive path of the world and agent nodes (``transport.Receiver``): tag check, decoder, runtime.
The only outcomes are acceptance or a clean rejection (a reason the node logs); no other
exception may escape, as it would from a subscription callback."""

from __future__ import annotations

import contextlib
import importlib

import ost_msgs.msg as ros
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rclpy.serialization import serialize_message

from ost_msgs_py import auth, wire
from ost_ros.coordination import CoordinationPolicy
from ost_ros.lockstep.agent import AgentRuntime, ProtocolViolation
from ost_ros.lockstep.messages import Acted, AgentReport, Ready, Resend, RunEnd, RunInfo, Tick
from ost_ros.lockstep.world import WorldRuntime
from ost_ros.model import Grid
from ost_ros.node import transport as tp
from ost_ros.node.signing import NodeAuth
from ost_ros.protocols import make_agents
from ost_ros.scenario import generate_scenario

RANGES = {
    "int8": (-(2**7), 2**7 - 1), "uint8": (0, 2**8 - 1), "uint16": (0, 2**16 - 1),
    "int32": (-(2**31), 2**31 - 1), "uint32": (0, 2**32 - 1),
    "int64": (-(2**63), 2**63 - 1), "uint64": (0, 2**64 - 1),
}  # fmt: skip
HUGE = 100_000  # elements of an array far beyond any run's


def ints(kind: str):
    lo, hi = RANGES[kind]
    edges = [lo, hi, 0, 1, -1, 2**31 - 1] if lo < 0 else [lo, hi, 0, 1]
    return st.one_of(st.sampled_from([e for e in edges if lo <= e <= hi]), st.integers(lo, hi))


TEXT = st.one_of(
    st.sampled_from(
        ["", "wait", "move", "carry", "jump", "SEARCHING", "FINISH", "ccp", "offer", "x" * 10_000]
    ),
    st.text(max_size=30),
)


def values(field_type: str):
    if field_type in RANGES:
        return ints(field_type)
    if field_type == "boolean":
        return st.booleans()
    if field_type in ("double", "float"):  # NaN and the infinities too
        return st.floats(width=64 if field_type == "double" else 32)
    if field_type == "string":
        return TEXT
    if field_type.startswith("sequence<"):
        inner = field_type[len("sequence<") : -1]
        small = st.lists(values(inner), max_size=6)
        if inner in RANGES:  # and now and then a huge one
            return st.one_of(small, st.builds(lambda v: [v] * HUGE, ints(inner)))
        return small
    pkg, name = field_type.split("/")
    return messages(getattr(importlib.import_module(f"{pkg}.msg"), name))


def messages(cls):
    fields = cls.get_fields_and_field_types()
    return st.builds(lambda kw: cls(**kw), st.fixed_dictionaries({n: values(t) for n, t in fields.items()}))


SCENARIO = generate_scenario(3, 4, 1, Grid(20, 8), 2)
IDS = (0, 1, 2)
KEYS: dict = {}


def secure(tmp_path_factory) -> NodeAuth:
    """Agent 0's part in a secure run (one per test: its counts and replay windows)."""
    if "keys" not in KEYS:
        d = KEYS["dir"] = tmp_path_factory.mktemp("keys")
        KEYS["keys"] = auth.Keys(auth.make_keys(d, IDS), 0, auth.load_private(d, 0))
    return NodeAuth(KEYS["keys"])


class Log:
    def __init__(self):
        self.lines: list[str] = []

    def warning(self, text: str) -> None:
        self.lines.append(text)


def receive(data: bytes, kind: type, topic: str, guard, accept) -> None:
    """What a node's raw subscription does (transport.Receiver, then AgentRunner._feed or
    WorldNode.on_*): check, decode, accept."""
    r = tp.Receiver(kind, lambda m: None, guard, tp.Throttle(Log()))
    r.topic = topic
    m = r.receive(data)
    if m is not None:
        with contextlib.suppress(ProtocolViolation):
            accept(m)


def agent_runtime() -> AgentRuntime:
    rt = AgentRuntime(make_agents(SCENARIO, "ccp", CoordinationPolicy())[0], IDS)
    rt.accept_tick(WorldRuntime(SCENARIO, run="r").start()[0])  # a run under way: run id "r"
    return rt


def world_runtime() -> WorldRuntime:
    w = WorldRuntime(SCENARIO, run="r")
    w.start()
    return w


AGENT_SIDE = {Tick: "accept_tick", RunEnd: "accept_end", Resend: "accept_resend"}
WORLD_SIDE = {Acted: "accept_acted", AgentReport: "accept_report"}
FUZZ = settings(
    max_examples=int(__import__("os").environ.get("OST_FUZZ_EXAMPLES", "60")),
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)


def _check(cls, data, guard) -> list:
    """Feed one random message of ``cls`` to the runtime that receives it; what got through."""
    msg = data.draw(messages(wire.ros_type(cls)))
    if hasattr(msg, "run") and data.draw(st.booleans()):
        msg.run = "r"  # the run's own id: past the run check, into the runtime
    raw = serialize_message(msg)
    damage = data.draw(st.sampled_from(["none", "none", "cut", "flip"]))
    if damage == "cut":
        raw = raw[: data.draw(st.integers(0, len(raw)))]
    elif damage == "flip" and raw:
        k = data.draw(st.integers(0, len(raw) - 1))
        raw = raw[:k] + bytes([raw[k] ^ data.draw(st.integers(1, 255))]) + raw[k + 1 :]
    through: list = []

    def into(accept):
        return lambda m: (through.append(m), accept(m))

    if cls in WORLD_SIDE:
        receive(raw, cls, "/ost/x", guard, into(getattr(world_runtime(), WORLD_SIDE[cls])))
    elif cls is Ready:
        receive(raw, cls, "/ost/ready", guard, into(lambda r: None))
    else:
        rt = agent_runtime()
        receive(raw, cls, "/ost/x", guard, into(getattr(rt, AGENT_SIDE.get(cls, "accept_sample"))))
        rt.held()
    return through


# What the run's nodes receive: every interface but RunInfo (read by tools: ost replay, live view)
RECEIVED = [*wire.PROTOCOL_MESSAGES, Ready, *AGENT_SIDE, *WORLD_SIDE]


def test_every_interface_is_covered():
    assert {*RECEIVED, RunInfo} == {*wire.PROTOCOL_MESSAGES, *wire.RUNTIME_MESSAGES}


@FUZZ
@given(data=st.data(), cls=st.sampled_from(RECEIVED))
def test_random_messages_are_accepted_or_cleanly_refused(data, cls):
    _check(cls, data, NodeAuth())


@FUZZ
@given(data=st.data(), cls=st.sampled_from(RECEIVED))
def test_random_messages_in_a_secure_run_are_dropped(tmp_path_factory, data, cls):
    guard = secure(tmp_path_factory)
    assert _check(cls, data, guard) == []  # nothing unsealed or forged gets in
    assert sum(guard.counts().values()) == 1


@FUZZ
@given(data=st.data())
def test_random_run_info_decodes_or_is_refused(data):
    msg = data.draw(messages(ros.RunInfo))
    with contextlib.suppress(wire.MessageError):
        wire.from_ros(msg)
    with contextlib.suppress(wire.MessageError):
        wire.from_cdr(RunInfo, serialize_message(msg))
