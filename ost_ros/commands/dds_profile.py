"""The Fast DDS profile of a realtime run on this host (docs/ros.md, "Transport"): the
loopback profile (``ost_ros/dds/fastdds_localhost_udp.xml``) plus, for each topic every robot
reads, a reader profile on the domain's user multicast locator — a writer then sends a sample
once, and the kernel hands each participant its copy, instead of one datagram per reader (at
N=50, 51 a sample). Topics one node reads (a base's events, digests, goals) stay unicast: on the
multicast locator every participant would receive them. Written into the run's directory, for
the run's namespace and protocol (rmw_fastrtps looks reader profiles up by full topic name)."""

from __future__ import annotations

from pathlib import Path

from ost_ros.realtime.topics import everyone_reads

# The domain's user multicast locator: no port given, so Fast DDS takes the well-known one
# (7401 + 250 x domain) and runs in other domains on this host never hear each other.
GROUP = "239.255.0.1"
EDP_ANCHOR = "</discovery_config>\n"
EDP_MULTICAST = "        <avoid_builtin_multicast>false</avoid_builtin_multicast>\n"


def realtime_profile(base: str, namespace: str, protocol: str, organisation: str, fanout: str) -> str:
    """``base`` (a profiles document) with the multicast reader profiles of a realtime run (with
    ``fanout:=monitor`` the robots read the monitor's bundles, not each other's topics)."""
    ns = "/" + namespace.strip("/") if namespace.strip("/") else ""
    readers = "".join(
        f'  <data_reader profile_name="{ns}/{topic}">\n'
        f"    <multicastLocatorList><locator><udpv4><address>{GROUP}</address></udpv4></locator>"
        "</multicastLocatorList>\n"
        "  </data_reader>\n"
        for topic in everyone_reads(protocol, organisation, fanout)
    )
    head, sep, tail = base.rpartition("</profiles>")
    if not sep:
        raise ValueError("not a Fast DDS profiles document (no </profiles>)")
    # Endpoint discovery by multicast too (Fast DDS avoids it by default): a participant then
    # announces each endpoint once to the host, not once per participant. With the readers on
    # multicast and without it, a team of 50 came up in 62-72 s against 42-50 s before; with it
    # in 36-40 s (docs/benchmarks.md).
    if EDP_ANCHOR not in head:
        raise ValueError("not the loopback profile (no </discovery_config> to add endpoint discovery to)")
    head = head.replace(EDP_ANCHOR, EDP_ANCHOR + EDP_MULTICAST, 1)
    return f"{head}  <!-- the readers of what every robot reads, on multicast (ost_ros/commands/dds_profile.py) -->\n{readers}{sep}{tail}"


def write_realtime_profile(
    path: Path, base: Path, namespace: str, protocol: str, organisation: str, fanout: str
) -> None:
    """The run's profile (:func:`realtime_profile` of the file ``base``) written to ``path``."""
    path.write_text(realtime_profile(base.read_text(), namespace, protocol, organisation, fanout))
