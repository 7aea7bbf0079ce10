"""Several hosts and lossy links (root: network namespaces on a bridge, bringup_scripts/
sim_hosts.sh): the world and the agents on K = 3 simulated hosts with their own IPs give exactly
the single-host run (= ``ost sim``) — with default multicast discovery, with multicast blocked
and ROS_STATIC_PEERS or a Fast DDS discovery server instead, and with 20 % of every packet each
host sends dropped (nftables ``numgen``); a realtime run on lossy hosts keeps the protocol's
promise; and a partition between the hosts of two groups of robots heals."""

import os
import shutil
import subprocess

import pytest

from ost_ros.coordination import CoordinationPolicy
from ost_ros.model import Grid
from ost_ros.scenario import dump_scenario, generate_scenario
from tests.ros.dds_helpers import REPO, kept_its_promise, ost_up, reference, result_json

ROOT = os.geteuid() == 0
NFT = shutil.which("nft") is not None
pytestmark = [
    pytest.mark.root,
    pytest.mark.skipif(not ROOT, reason="simulated hosts need root (network namespaces)"),
]


def run_on_hosts(tmp_path, *args, protocol="ccp"):
    scenario = generate_scenario(4, 8, 1, Grid(30, 12), 4)
    path = tmp_path / "s.yaml"
    path.write_text(dump_scenario(scenario))
    expected = reference(scenario, protocol, CoordinationPolicy(ci=1))
    run = ost_up(
        "--scenario",
        str(path),
        "--json",
        "--protocol",
        protocol,
        "--hosts",
        "3",
        *args,
        "--run-dir",
        str(tmp_path / "run"),
        timeout=300,
    )
    assert run.returncode == 0, run.stderr
    assert "on 3 simulated hosts" in run.stderr
    return result_json(run.stdout), expected, run.stderr


def no_namespaces_left(stderr: str) -> bool:
    name = "ost" + stderr.split("ROS_DOMAIN_ID=")[1].split(",")[0]
    listed = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True).stdout
    return not any(line.split()[0].startswith(name + "_") for line in listed.splitlines() if line)


def test_three_hosts_multicast_discovery(tmp_path):
    got, expected, err = run_on_hosts(tmp_path)
    assert got == expected
    assert no_namespaces_left(err)


@pytest.mark.skipif(not NFT, reason="nft (Debian package nftables) is needed to block multicast")
@pytest.mark.parametrize("discovery", ["static", "server"])
def test_multicast_blocked_static_peers_or_discovery_server(tmp_path, discovery):
    got, expected, err = run_on_hosts(tmp_path, "--discovery", discovery)
    assert got == expected
    assert f"discovery {discovery}" in err


@pytest.mark.skipif(not NFT, reason="nft (Debian package nftables) is needed to drop packets")
@pytest.mark.parametrize("protocol", ["ccp", "ncp"])
def test_twenty_percent_loss_on_every_host(tmp_path, protocol):
    got, expected, err = run_on_hosts(tmp_path, "--loss", "20", protocol=protocol)
    assert got == expected
    assert "loss 20 %" in err


@pytest.mark.skipif(not NFT, reason="nft (Debian package nftables) is needed to drop packets")
def test_a_realtime_run_on_lossy_hosts_keeps_the_promise(tmp_path):
    """No barrier and no Resend: reliable DDS repairs what is lost (the hosts' profile has a
    100 ms heartbeat), so a lossy link costs time, never the agreement. The liveliness lease is
    longer than the default 1 s: at 20 % loss a live robot's assertions can lapse for 2 s and the
    world would declare it failed (the robot then leaves, and an object needing all four is
    stranded)."""
    scenario = generate_scenario(4, 8, 1, Grid(30, 12), 4)
    path = tmp_path / "s.yaml"
    path.write_text(dump_scenario(scenario))
    run = ost_up(
        "--scenario", str(path), "--realtime", "--rtf", "20", "--hosts", "3", "--loss", "20",
        "--failure-timeout", "5", "--json", "--run-dir", str(tmp_path / "run"), "--timeout", "240",
        timeout=300,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr[-3000:]
    assert "loss 20 %" in run.stderr
    kept_its_promise(result_json(run.stdout), 8)
    assert no_namespaces_left(run.stderr)


@pytest.mark.skipif(not NFT, reason="nft (Debian package nftables) is needed to cut the hosts apart")
@pytest.mark.parametrize("seconds", [5, 25])
def test_a_partition_between_hosts_heals(tmp_path, seconds):
    """``--split``: robots 0-2 and 3-5 on two hosts with no traffic between them (a bridge
    rule), the world and the membership node on a third that reaches both. 5 s: DDS keeps the
    peers (their participants' lease is 20 s) and repairs what crossed; 25 s: DDS drops the
    peers, what was published meanwhile is lost for good, and when the readers come back each
    robot says its messages and watermark again. Either way: every object delivered, the same
    schedule everywhere, nobody declared out, each side waited for the other (no split brain)."""
    path = tmp_path / "s.yaml"
    path.write_text(dump_scenario(generate_scenario(6, 8, 1, Grid(60, 20), 3)))  # finds until 79
    run = ost_up(
        "--scenario", str(path), "--realtime", "--rtf", "20", "--hosts", "3",
        "--split", f"0,1,2/3,4,5:30:{seconds}", "--fanout", "direct", "--json", "--run-dir", str(tmp_path / "run"),
        "--timeout", "240", timeout=300,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr[-3000:]
    assert "split 0,1,2 | 3,4,5: no traffic between them" in run.stderr and "split healed" in run.stderr
    result = result_json(run.stdout)
    kept_its_promise(result, 8)
    m = result["membership"]
    assert m["declared"] == 0 and m["out_at_end"] == [] and result["failures"] == []
    (split,) = m["splits"]
    assert split["groups"] == [[0, 1, 2], [3, 4, 5]] and split["healed"] is not None
    assert split["healed"] - split["from"] >= seconds * 20 * 0.9  # (sim time passed while cut)
    assert result["makespan"] > split["healed"]  # the team waited for the heal
    assert split["agree_after_s"] is not None
    assert no_namespaces_left(run.stderr)


def test_sim_hosts_bad_arguments_are_one_line():
    script = REPO / "bringup_scripts" / "sim_hosts.sh"
    for args, text in [
        (["up", "x"], "required: k"),
        (["up", "bad-name!", "2"], "NAME"),
        (["up", "x", "0"], "K: 1..250"),
        (["sideways", "x"], "invalid choice: 'sideways'"),
    ]:
        r = subprocess.run(["bash", str(script), *args], capture_output=True, text=True)
        assert r.returncode == 2 and text in r.stderr and len(r.stderr.strip().splitlines()) == 1
