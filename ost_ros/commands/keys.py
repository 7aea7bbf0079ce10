"""``ost keys``: the key material of a secure DDS run (docs/ros.md, "Authenticated messages").

``ost keys make DIR --scenario FILE`` writes one X25519 key per robot of the scenario's team, one
for the world and one for the membership monitor of realtime runs (``agent_<i>.key``,
``world.key``, ``membership.key``: mode 0600, each node reads only its own; any
two members derive from them the key they seal their messages to each other with) and
``team.yaml`` (the run id and every public key, which every node reads).
``ost_up.sh`` and the launch file do it for every run; ``ost keys show DIR`` prints what a
directory holds.
"""

from __future__ import annotations

import argparse
import hashlib
import json

from ost_ros.commands.args import OneLineParser, leaf, load_scenario_arg
from ost_ros.errors import UsageError


def register(sub) -> None:
    keys = sub.add_parser(
        "keys",
        help="key material of a secure DDS run (sealed messages)",
        description="Keys for a run: one per robot and one for the world.",
    )
    verbs = keys.add_subparsers(dest="keys_verb", metavar="VERB", parser_class=OneLineParser)
    p = leaf(verbs, "make", cmd_make, help="new keys for a team: DIR/agent_<i>.key, world.key, team.yaml")
    p.add_argument("dir", help="the key directory (created, mode 0700)")
    p.add_argument("--scenario", help="the run's scenario: keys for its team")
    p.add_argument("--agents", type=int, help="team size (replaces the scenario's team; alone: ids 0..N-1)")
    p.add_argument("--run", help="the run id (default: random)")
    p = leaf(verbs, "show", cmd_show, help="the run id and signers of a key directory")
    p.add_argument("dir", help="the key directory")
    p.add_argument("--json", action="store_true", help="print JSON")


def cmd_make(args: argparse.Namespace) -> int:
    from ost_msgs_py.auth import make_keys

    if args.agents is not None and args.agents < 1:
        raise UsageError(f"--agents: {args.agents} (must be at least 1)")
    if args.scenario:
        ids = [a.id for a in load_scenario_arg(args.scenario, args.agents).agents]
    elif args.agents:
        ids = list(range(args.agents))
    else:
        raise UsageError("give --scenario FILE or --agents N")
    if args.run is not None and not (args.run.isascii() and args.run.isalnum()):
        raise UsageError(f"--run: {args.run!r} (letters and digits only)")
    try:
        team = make_keys(args.dir, ids, args.run)
    except OSError as exc:
        raise UsageError(f"{args.dir}: cannot write keys ({exc.strerror})") from None
    print(f"{args.dir}: keys for the world, the membership monitor and {len(ids)} agents, run {team.run}")
    return 0


def cmd_show(args: argparse.Namespace) -> int:
    from cryptography.hazmat.primitives import serialization

    from ost_msgs_py.auth import MEMBERSHIP, WORLD, AuthError, load_team, signer_name

    try:
        team = load_team(args.dir)
    except AuthError as exc:
        raise UsageError(str(exc)) from None

    def fingerprint(key) -> str:
        raw = key.public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw)
        return hashlib.sha256(raw).hexdigest()[:16]

    names = {WORLD: "world", MEMBERSHIP: "membership"}
    signers = {names.get(s, str(s)): fingerprint(k) for s, k in sorted(team.keys.items())}
    if args.json:
        print(json.dumps({"run": team.run, "signers": signers}, indent=1))
        return 0
    agents = sum(1 for s in team.keys if s >= 0)
    print(
        f"run {team.run}: {agents} agents, the world{' and the membership monitor' if MEMBERSHIP in team.keys else ''}"
    )
    for s, k in sorted(team.keys.items()):
        print(f"  {signer_name(s):<22} sha256:{fingerprint(k)}")
    return 0
