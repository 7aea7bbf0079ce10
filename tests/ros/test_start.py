"""What every node process gets at its start: no thread pool it never uses, and sockets large
enough for a 50-robot run (docs/ros.md, "Lost datagrams, late announcements, idle threads")."""

import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.ros.dds_helpers import BIN, INSECURE, PROFILE, ros_env


def receive_buffer() -> int:
    """What the profile the nodes load asks for (<receiveBufferSize>, bytes)."""
    text = re.search(r"<receiveBufferSize>(\d+)</receiveBufferSize>", PROFILE.read_text())
    assert text is not None, f"{PROFILE}: no <receiveBufferSize>"
    return int(text.group(1))


@pytest.mark.parametrize("module", ["agent_node.agent_node", "world_node.world_node", "ost_ros.cli"])
def test_a_node_module_starts_no_threads(module):
    # numpy's OpenBLAS would start a thread per core on import (~0.15 CPU-s of every start);
    # rclpy's own threads are counted before (it does not load numpy)
    code = (
        "import os, rclpy; n = len(os.listdir('/proc/self/task')); "
        f"import {module}; print(len(os.listdir('/proc/self/task')) - n)"
    )
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env)
    assert out.stdout.strip() == "0"


def dds_ports(domain: int) -> range:
    """The UDP ports of a domain (RTPS: 7400 + 250 * domain, then the participants' ports)."""
    return range(7400 + 250 * domain, 7400 + 250 * (domain + 1))


@pytest.mark.skipif(shutil.which("ss") is None, reason="needs ss (iproute2) to read socket buffers")
def test_a_node_receives_on_sockets_of_the_profiles_size(tmp_path, procs, domain):
    from ost_ros.model import Grid
    from ost_ros.scenario import dump_scenario, generate_scenario

    path = tmp_path / "s.yaml"
    path.write_text(dump_scenario(generate_scenario(2, 2, 1, Grid(20, 10), 2)))
    procs.start("world", "world_node", "-p", f"scenario:={path}", *INSECURE)
    procs.wait_for("world", "waiting for 2 agents", timeout=60)
    pid = procs.procs["world"].pid
    listing = subprocess.run(["ss", "-u", "-a", "-m", "-n", "-p"], capture_output=True, text=True, check=True)
    # A socket's line (address, users:((...pid=...))) is followed by its skmem line.
    lines = listing.stdout.splitlines()
    sizes = {}
    for line, mem in zip(lines, lines[1:]):
        port = re.search(r"^\S+\s+\d+\s+\d+\s+\S+:(\d+)\s", line)
        size = re.search(r"\brb(\d+)", mem)
        if f"pid={pid}," in line and port and size and int(port.group(1)) in dds_ports(domain):
            sizes[int(port.group(1))] = int(size.group(1))
    assert sizes, f"no DDS socket of the world node found:\n{listing.stdout[-2000:]}"
    # Linux doubles what is asked (bookkeeping) and caps the request at net.core.rmem_max.
    cap = int(Path("/proc/sys/net/core/rmem_max").read_text())
    assert all(rb >= 2 * min(receive_buffer(), cap) for rb in sizes.values()), sizes


def sockets_of(pid: int) -> set[tuple[str, int]]:
    """(address, port) of the UDP sockets process ``pid`` holds (ss -u -a -n -p)."""
    listing = subprocess.run(["ss", "-u", "-a", "-n", "-p"], capture_output=True, text=True, check=True)
    found = set()
    for line in listing.stdout.splitlines():
        local = re.search(r"^\S+\s+\d+\s+\d+\s+(\S+):(\d+)\s", line)
        if f"pid={pid}," in line and local:
            found.add((local.group(1), int(local.group(2))))
    return found


@pytest.mark.skipif(shutil.which("ss") is None, reason="needs ss (iproute2) to list a process's sockets")
def test_a_robot_reads_its_peers_on_the_domains_multicast_port(tmp_path, procs, domain):
    # (docs/ros.md, "Transport": with a realtime run's profile a writer sends a sample once to
    # the domain's user multicast locator, 239.255.0.1 at 7401 + 250 x domain, not once per reader)
    from ost_ros.commands.dds_profile import write_realtime_profile
    from ost_ros.model import Grid
    from ost_ros.scenario import dump_scenario, generate_scenario

    path = tmp_path / "s.yaml"
    path.write_text(dump_scenario(generate_scenario(2, 2, 1, Grid(20, 10), 2)))
    env = ros_env(domain)
    profile = tmp_path / "fastdds.xml"
    write_realtime_profile(profile, PROFILE, "ost", "ccp", "distributed", "monitor")
    env["FASTRTPS_DEFAULT_PROFILES_FILE"] = str(profile)
    common = ["-p", f"scenario:={path}", "-p", "realtime:=true", *INSECURE]
    procs.run("agent_0", [str(BIN / "agent_node"), "--ros-args", *common, "-p", "agent_id:=0"], env=env)
    pid, port = procs.procs["agent_0"].pid, 7401 + 250 * domain
    end = time.monotonic() + 60
    while not any(p == port for _, p in sockets_of(pid)) and time.monotonic() < end:
        assert procs.procs["agent_0"].poll() is None, procs.log("agent_0")
        time.sleep(0.2)  # (its subscriptions are made in its constructor: polled until then)
    assert any(p == port for _, p in sockets_of(pid)), sorted(sockets_of(pid))
