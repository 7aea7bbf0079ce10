"""Simulated hosts on one machine: K network namespaces, each with its own IP on one Linux bridge
(the bridge sits in a namespace of its own, so the root namespace is untouched). Needs root and
``ip`` (iproute2); ``--loss`` and ``--block-multicast`` need ``nft`` (nftables).

    python -m ost_ros.commands.hosts up NAME K [--net N] [--loss PCT] [--block-multicast]
    python -m ost_ros.commands.hosts down NAME

``up``: hosts NAME_h0 .. NAME_h{K-1} with addresses 10.77.N.1 .. 10.77.N.K (/24), printed one per
line. ``--loss PCT`` drops PCT % of every packet a host sends (nftables ``numgen random``, inside the
host's namespace); ``--block-multicast`` drops multicast (224.0.0.0/4) on the bridge, so DDS
discovery needs ROS_STATIC_PEERS or a discovery server. ``down``: deletes NAME's namespaces.
:func:`cut` and :func:`heal` part groups of hosts and join them again (``ost up --split``). Run a
command on host i with ``ip netns exec NAME_h<i> COMMAND``. ``ost up --hosts K`` uses this.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys

from ost_ros.commands.args import OneLineParser
from ost_ros.errors import UsageError


def _run(*argv: str, stdin: str | None = None) -> None:
    p = subprocess.run(argv, input=stdin, capture_output=True, text=True)
    if p.returncode:
        raise UsageError(f"{' '.join(argv)}: {(p.stderr or p.stdout).strip()}")


def host(name: str, i: int) -> str:
    """The namespace of simulated host ``i``."""
    return f"{name}_h{i}"


def down(name: str) -> None:
    """Delete every namespace of the set ``name`` (none is fine)."""
    listed = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True).stdout
    pattern = re.compile(rf"^{re.escape(name)}_(sw|h\d+)$")
    for ns in (line.split()[0] for line in listed.splitlines() if line.strip()):
        if pattern.match(ns):
            subprocess.run(["ip", "netns", "del", ns], capture_output=True)


def up(name: str, k: int, net: int = 77, loss: int = 0, block_multicast: bool = False) -> list[str]:
    """Create the hosts; their addresses, in host order. A failure removes what was made."""
    if not re.fullmatch(r"[A-Za-z0-9_]{1,20}", name):
        raise UsageError(f"NAME: letters, digits and _ only (1-20), got {name!r}")
    if os.geteuid() != 0:
        raise UsageError("simulated hosts need root (network namespaces)")
    if shutil.which("ip") is None:
        raise UsageError("ip (iproute2) not found")
    for what, value, hi in (("K", k, 250), ("--net", net, 255), ("--loss", loss, 100)):
        if not (1 if what == "K" else 0) <= value <= hi:
            raise UsageError(f"{what}: {1 if what == 'K' else 0}..{hi}, got {value}")
    if (loss or block_multicast) and shutil.which("nft") is None:
        raise UsageError("nft not found (Debian package nftables) for --loss / --block-multicast")
    down(name)  # a previous set of the same name
    sw = f"{name}_sw"
    try:
        _run("ip", "netns", "add", sw)
        _run("ip", "netns", "exec", sw, "ip", "link", "add", "br0", "type", "bridge")
        _run("ip", "netns", "exec", sw, "ip", "link", "set", "br0", "up")
        if block_multicast:
            rule = "table bridge ost {\n chain forward {\n  type filter hook forward priority 0; ip daddr 224.0.0.0/4 drop\n }\n}\n"
            _run("ip", "netns", "exec", sw, "nft", "-f", "-", stdin=rule)
        ips = []
        for i in range(k):
            h, ip = host(name, i), f"10.77.{net}.{i + 1}"
            _run("ip", "netns", "add", h)
            _run(
                "ip",
                "netns",
                "exec",
                sw,
                "ip",
                "link",
                "add",
                f"p{i}",
                "type",
                "veth",
                "peer",
                "name",
                "eth0",
                "netns",
                h,
            )
            _run("ip", "netns", "exec", sw, "ip", "link", "set", f"p{i}", "master", "br0", "up")
            _run("ip", "netns", "exec", h, "ip", "link", "set", "lo", "up")
            _run("ip", "netns", "exec", h, "ip", "addr", "add", f"{ip}/24", "dev", "eth0")
            _run("ip", "netns", "exec", h, "ip", "link", "set", "eth0", "up")
            # multicast (discovery) goes out on eth0
            _run("ip", "netns", "exec", h, "ip", "route", "add", "default", "dev", "eth0")
            if loss:
                rule = (
                    "table inet ost {\n chain output {\n  type filter hook output priority 0; "
                    f'oifname "eth0" numgen random mod 100 < {loss} drop\n }}\n}}\n'
                )
                _run("ip", "netns", "exec", h, "nft", "-f", "-", stdin=rule)
            ips.append(ip)
    except BaseException:
        down(name)
        raise
    return ips


def cut(name: str, groups: list[list[int]], tag: int = 0) -> None:
    """No traffic between the hosts of different ``groups`` (host indices), multicast included:
    a bridge rule on the switch between their ports (table ``split<tag>``), until :func:`heal`.
    Hosts in no group reach everyone."""
    if shutil.which("nft") is None:
        raise UsageError("nft not found (Debian package nftables) for --split")
    ports = [", ".join(f'"p{h}"' for h in g) for g in groups]
    rules = "".join(
        f"  iifname {{ {a} }} oifname {{ {b} }} drop\n"
        for i, a in enumerate(ports)
        for j, b in enumerate(ports)
        if i != j
    )
    table = f"table bridge split{tag} {{\n chain forward {{\n  type filter hook forward priority -10;\n{rules} }}\n}}\n"
    _run("ip", "netns", "exec", f"{name}_sw", "nft", "-f", "-", stdin=table)


def heal(name: str, tag: int = 0) -> None:
    """Undo :func:`cut` ``tag``."""
    _run("ip", "netns", "exec", f"{name}_sw", "nft", "delete", "table", "bridge", f"split{tag}")


def main(argv: list[str] | None = None) -> int:
    p = OneLineParser(prog="sim_hosts", description=__doc__.split("\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True, parser_class=OneLineParser)
    u = sub.add_parser("up")
    u.add_argument("name")
    u.add_argument("k", type=int)
    u.add_argument("--net", type=int, default=77)
    u.add_argument("--loss", type=int, default=0)
    u.add_argument("--block-multicast", action="store_true")
    d = sub.add_parser("down")
    d.add_argument("name")
    args = p.parse_args(argv)
    try:
        if args.cmd == "down":
            down(args.name)
        else:
            print("\n".join(up(args.name, args.k, args.net, args.loss, args.block_multicast)))
    except UsageError as exc:
        print(f"sim_hosts: error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
