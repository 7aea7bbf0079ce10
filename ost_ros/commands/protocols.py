"""``ost protocols``: the protocol registry — ``list`` what is registered and what each protocol
can run; ``check`` a combination (one line and exit code 2 if it cannot run; scripts such as
``ost_up.sh`` ask this before starting processes)."""

from __future__ import annotations

import argparse
import json
from dataclasses import asdict

from ost_ros import protocols
from ost_ros.commands.args import leaf
from ost_ros.coordination import ORGANISATIONS, CoordinationPolicy
from ost_ros.errors import UsageError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("protocols", help="the registered cooperation protocols and what they can run")
    verbs = p.add_subparsers(dest="protocols_verb", metavar="VERB", parser_class=type(p))
    ls = leaf(verbs, "list", cmd_list, help="every protocol: capabilities, options, messages")
    ls.add_argument("--names", action="store_true", help="the names only, one line")
    ls.add_argument("--json", action="store_true", help="print JSON")
    ck = leaf(verbs, "check", cmd_check, help="exit 2 with the reason if a protocol cannot run this")
    ck.add_argument("name", help="protocol name")
    ck.add_argument("--coordination", choices=ORGANISATIONS, default="distributed")
    ck.add_argument("--failures", action="store_true", help="robots may fail (survivors re-plan)")
    ck.add_argument(
        "--own-sweeps", action="store_true", help="robots with their own sweeps (negotiated areas)"
    )
    ck.add_argument("--silence", action="store_true", help="a negotiator falls silent (fault injection)")
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1], prog=p.prog)


def describe(spec: protocols.ProtocolSpec) -> dict:
    return {
        "name": spec.name,
        "label": spec.label,
        "title": spec.title,
        "capabilities": asdict(spec.capabilities),
        "states": list(spec.states),
        "messages": [m.__name__ for m in spec.messages],
        "topics": [getattr(m, "TYPE") for m in spec.messages],  # noqa: B009 - relative: /ost/<kind>
        "options": {o.name: protocols.option_default(spec, o) for o in spec.options},
    }


def cmd_list(args: argparse.Namespace) -> int:
    if args.names:
        print(" ".join(protocols.names()))
        return 0
    rows = [describe(s) for s in protocols.REGISTRY.values()]
    if args.json:
        print(json.dumps(rows, indent=1))
        return 0
    for r in rows:
        caps = r["capabilities"]
        can = [k.replace("_", " ") for k, v in caps.items() if v is True]
        print(f"{r['name']}  {r['title']}")
        print(f"     organisations: {', '.join(caps['organisations'])}; also: {', '.join(can) or '-'}")
        print(f"     messages (topic /ost/<kind> each): {', '.join(r['topics'])}")
        if r["options"]:
            print("     options: " + ", ".join(f"{k} (default {v})" for k, v in r["options"].items()))
    return 0


def cmd_check(args: argparse.Namespace) -> int:
    try:
        spec = protocols.check(
            args.name,
            policy=CoordinationPolicy(organisation=args.coordination),
            failures=args.failures,
            silence=args.silence,
        )
    except protocols.ProtocolError as exc:
        raise UsageError(str(exc)) from None
    if args.own_sweeps and not spec.capabilities.own_sweeps:
        able = " or ".join(n for n, s in protocols.REGISTRY.items() if s.capabilities.own_sweeps)
        raise UsageError(
            f"{args.name} cannot run robots with their own sweeps (a negotiated partition); use {able}"
        )
    return 0
