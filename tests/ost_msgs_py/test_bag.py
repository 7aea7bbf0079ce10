"""Recordings (``ost_msgs_py.bag``): rosbag2's MCAP layout — full ``ros2msg`` definitions that an
independent decoder (mcap-ros2-support) understands, CDR as rclpy sends it, and a summary as
``ros2 bag info`` prints it. Bad files are one-line errors."""

import pytest
from mcap.reader import make_reader
from mcap_ros2._dynamic import generate_dynamic
from mcap_ros2.decoder import DecoderFactory
from rclpy.serialization import serialize_message

from ost_msgs_py import bag, wire
from ost_msgs_py.wire import PROTOCOL_MESSAGES
from ost_ros.lockstep.messages import RUNTIME_MESSAGES, Tick
from ost_ros.messages import AgentLost, ObjectInfo, Observation
from ost_ros.node import transport as tp


@pytest.mark.parametrize("cls", [*PROTOCOL_MESSAGES, *RUNTIME_MESSAGES], ids=lambda c: c.__name__)
def test_every_definition_parses_with_its_nested_types(cls):
    name = wire.type_name(cls)
    text = bag.message_definition(name)
    assert text.startswith(bag._msg_file("ost_msgs", cls.__name__).read_text().rstrip("\n"))
    types = generate_dynamic(name, text)  # the independent parser Foxglove's tools use
    assert name in types


def test_tick_brings_observation_cell_objects_and_notices():
    text = bag.message_definition("ost_msgs/msg/Tick")
    sections = [line[5:] for line in text.splitlines() if line.startswith("MSG: ")]
    assert {"ost_msgs/Observation", "ost_msgs/Cell", "ost_msgs/ObjectInfo", "ost_msgs/AgentLost"} <= set(
        sections
    )
    assert len(sections) == len(set(sections))


def tick() -> Tick:
    seen = (ObjectInfo(3, (4, 5), (9, 9), 2),)
    return Tick(7, 5, Observation(1, 7, (4, 4), seen), (0, 2), (1, 3), "run1", (AgentLost(2, 6, seen),))


def test_written_messages_read_back_and_decode_independently(tmp_path):
    path = tmp_path / "r.mcap"
    w = bag.BagWriter(path)
    ch = w.channel("/ost/agent_1/tick", "ost_msgs/msg/Tick", tp.LOCKSTEP_QOS)
    cdr = serialize_message(wire.to_ros(tick()))
    for k in range(3):
        w.write(ch, cdr, 1_000 + k)
    w.write(w.channel("/ost/clock", "rosgraph_msgs/msg/Clock"), b"\0\1\0\0" + bytes(8), 2_000)
    w.close()
    w.close()  # twice is harmless
    got = list(bag.read(path))
    assert [r.topic for r in got] == ["/ost/agent_1/tick"] * 3 + ["/ost/clock"]
    assert wire.from_ros(bag.decode(got[0])) == tick()
    # mcap-ros2-support decodes the same bytes from the stored schema alone (no rclpy)
    with open(path, "rb") as f:
        msgs = list(make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages())
    decoded = msgs[0].decoded_message
    assert decoded.observation.sensed[0].id == 3 and list(decoded.peers) == [0, 2]
    assert decoded.failed[0].agent == 2 and decoded.run == "run1"
    info = bag.info(path)
    assert info.messages == 4 and info.profile == "ros2"
    counts = {t.topic: (t.type_name, t.count) for t in info.topics}
    assert counts == {
        "/ost/agent_1/tick": ("ost_msgs/msg/Tick", 3),
        "/ost/clock": ("rosgraph_msgs/msg/Clock", 1),
    }
    assert "history: keep_all" in info.topics[0].qos and "reliability: reliable" in info.topics[0].qos
    text = info.text()
    assert "Messages:          4" in text and "Topic: /ost/agent_1/tick" in text and "Count: 3" in text


def test_bad_files_are_named(tmp_path):
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"not an mcap file at all")
    for call in (bag.info, lambda p: list(bag.read(p))):
        with pytest.raises(bag.BagError, match=r"junk\.mcap"):
            call(junk)
        with pytest.raises(bag.BagError, match="no such file"):
            call(tmp_path / "missing.mcap")
    with pytest.raises(bag.BagError, match="cannot write"):
        bag.BagWriter(tmp_path / "no" / "dir.mcap")
    with pytest.raises(bag.BagError, match="no definition of ost_msgs/msg/Nothing"):
        bag.message_definition("ost_msgs/msg/Nothing")
