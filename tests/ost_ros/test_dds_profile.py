"""The Fast DDS profile of a realtime run on this host (ost_ros/commands/dds_profile.py;
docs/ros.md, "Transport"): the topics every robot reads are delivered by multicast, and only
those; the lockstep and a user's own profile are left as they are."""

import xml.etree.ElementTree as ET

import pytest

from ost_ros import protocols
from ost_ros.cli import main as ost
from ost_ros.commands import bringup
from ost_ros.commands.dds_profile import realtime_profile
from ost_ros.node import realtime as rtp
from ost_ros.node import transport as tp
from ost_ros.realtime.topics import everyone_reads

NS = "{http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles}"


def multicast_readers(text: str) -> dict[str, list[tuple[str | None, str | None]]]:
    """Reader profile (full topic name) → its multicast locators (address, port or None)."""
    out = {}
    for reader in ET.fromstring(text).iter(f"{NS}data_reader"):
        listed = reader.find(f"{NS}multicastLocatorList")
        udp = [] if listed is None else list(listed.iter(f"{NS}udpv4"))
        out[reader.get("profile_name")] = [(u.findtext(f"{NS}address"), u.findtext(f"{NS}port")) for u in udp]
    return out


@pytest.mark.parametrize("protocol", protocols.names())
@pytest.mark.parametrize("organisation", ["distributed", "coordinator"])
@pytest.mark.parametrize("fanout", ["direct", "monitor"])
def test_every_topic_every_robot_reads_is_multicast_and_no_other(protocol, organisation, fanout):
    # what a realtime robot subscribes to from all its peers (agent_node/realtime.py): each
    # message kind's topic, the watermarks and hellos — with fanout:=monitor the monitor's
    # bundles of them instead —, the membership's notices, the bases' clock (a topic one node
    # reads on the multicast locator would reach every participant)
    if fanout == "direct":
        expected = {tp.message_topic(k) for k in rtp.message_kinds(protocol, organisation)}
        expected |= {rtp.MARKS, rtp.NEEDS, rtp.HELLOS}
    else:
        expected = {rtp.BUNDLES}
    expected |= {rtp.LOST, rtp.BASE_CLOCK}
    assert set(everyone_reads(protocol, organisation, fanout)) == expected
    text = realtime_profile(bringup.LOCALHOST_PROFILE.read_text(), "ost", protocol, organisation, fanout)
    readers = multicast_readers(text)
    assert set(readers) == {f"/ost/{t}" for t in expected}
    # no port: the domain's well-known user multicast port (7401 + 250 x domain), so runs in
    # other domains on this host never receive each other's samples
    assert all(locators == [("239.255.0.1", None)] for locators in readers.values()), readers
    # endpoint discovery by multicast too; the loopback profile's own settings are kept
    assert ET.fromstring(text).find(f".//{NS}avoid_builtin_multicast").text == "false"
    base = ET.fromstring(bringup.LOCALHOST_PROFILE.read_text())
    assert len(list(ET.fromstring(text).iter())) == len(list(base.iter())) + 5 * len(expected) + 1


@pytest.mark.parametrize("namespace", ["team2", "/team2", "fleet/team2"])
def test_the_profile_names_the_runs_namespace(namespace):
    readers = multicast_readers(
        realtime_profile(bringup.LOCALHOST_PROFILE.read_text(), namespace, "ccp", "distributed", "direct")
    )
    full = "/" + namespace.strip("/")
    assert f"{full}/marks" in readers and all(name.startswith(f"{full}/") for name in readers)


def test_not_the_loopback_profile_is_refused():
    with pytest.raises(ValueError, match="no </profiles>"):
        realtime_profile("<dds/>", "ost", "ccp", "distributed", "monitor")
    with pytest.raises(ValueError, match="no </discovery_config>"):
        realtime_profile("<profiles></profiles>", "ost", "ccp", "distributed", "monitor")


@pytest.fixture
def prepared(monkeypatch, tmp_path):
    monkeypatch.setattr(bringup, "DOMAIN_LOCKS", tmp_path / "locks")
    monkeypatch.setenv("FASTRTPS_DEFAULT_PROFILES_FILE", str(bringup.LOCALHOST_PROFILE))

    def prepare(*args: str) -> str:
        d = tmp_path / "run"
        small = ["--agents", "3", "--objects", "2", "--nmax", "2", "--width", "20", "--height", "10"]
        assert ost(["up", "--prepare", "--run-dir", str(d), *small, *args]) == 0
        return (d / "env.sh").read_text()

    return prepare


@pytest.mark.parametrize("fanout", [(), ("--fanout", "direct")], ids=["monitor (default)", "direct"])
def test_a_realtime_run_loads_its_own_profile_and_the_lockstep_the_loopback_one(prepared, tmp_path, fanout):
    env = prepared("--realtime", "--namespace", "blue", *fanout)
    profile = tmp_path / "run" / "fastdds.xml"
    assert f"FASTRTPS_DEFAULT_PROFILES_FILE={profile.resolve()}" in env
    readers = multicast_readers(profile.read_text())
    assert ("/blue/selection" in readers) == bool(fanout) and ("/blue/bundles" in readers) != bool(fanout)


def test_the_lockstep_keeps_the_loopback_profile(prepared, tmp_path):
    env = prepared()
    assert f"FASTRTPS_DEFAULT_PROFILES_FILE={bringup.LOCALHOST_PROFILE}" in env
    assert not (tmp_path / "run" / "fastdds.xml").exists()


def test_a_users_own_profile_is_kept(prepared, monkeypatch, tmp_path):
    mine = tmp_path / "mine.xml"
    mine.write_text(bringup.LOCALHOST_PROFILE.read_text())
    monkeypatch.setenv("FASTRTPS_DEFAULT_PROFILES_FILE", str(mine))
    assert f"FASTRTPS_DEFAULT_PROFILES_FILE={mine}" in prepared("--realtime")


def test_our_profile_by_another_path_is_ours(prepared, monkeypatch, tmp_path):
    # (a checkout reached through a symbolic link, as a shell's `pwd` names it)
    link = tmp_path / "link.xml"
    link.symlink_to(bringup.LOCALHOST_PROFILE)
    monkeypatch.setenv("FASTRTPS_DEFAULT_PROFILES_FILE", str(link))
    env = prepared("--realtime")
    assert f"FASTRTPS_DEFAULT_PROFILES_FILE={(tmp_path / 'run' / 'fastdds.xml').resolve()}" in env


def test_ros2_launch_gets_the_realtime_profile_as_ost_up_does(monkeypatch, tmp_path):
    # (launch/team.launch.py starts the nodes in the caller's environment plus run.env)
    monkeypatch.setattr(bringup, "DOMAIN_LOCKS", tmp_path / "locks")
    small = {"agents": "3", "objects": "2", "nmax": "2", "width": "20", "height": "10"}

    def launched(**given: str) -> dict[str, str]:
        d = tmp_path / f"run{len(list(tmp_path.glob('run*')))}"
        cfg = bringup.RunConfig.of({**small, **given, "run_dir": str(d)})
        return bringup.prepare(cfg, lambda _text: None, launch=True).env

    monkeypatch.setenv("FASTRTPS_DEFAULT_PROFILES_FILE", str(bringup.LOCALHOST_PROFILE))
    env = launched(realtime="true")
    assert list(env) == ["FASTRTPS_DEFAULT_PROFILES_FILE"] and env["FASTRTPS_DEFAULT_PROFILES_FILE"].endswith(
        "fastdds.xml"
    )
    assert launched() == {}  # the lockstep: the caller's environment as it is
    monkeypatch.setenv("FASTRTPS_DEFAULT_PROFILES_FILE", str(tmp_path / "mine.xml"))
    assert launched(realtime="true") == {}  # a profile of the caller's own
