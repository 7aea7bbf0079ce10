"""``ost faults report``: what robot failures (and, with ``--dds``, a real SIGKILL and a lossy
network) cost — objects delivered / total and the makespan's overhead over the fault-free run."""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

from ost_ros.commands.args import add_workers, at_least, executor, leaf
from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines import simulate
from ost_ros.errors import UsageError
from ost_ros.faults import HEADER, FaultRow, in_process_rows, markdown
from ost_ros.model import Grid
from ost_ros.scenario import dump_scenario, generate_scenario


def register(sub) -> None:
    p = sub.add_parser("faults", help="robot failures and lossy networks: the fault report")
    verbs = p.add_subparsers(dest="faults_verb", metavar="VERB", parser_class=type(p))
    r = leaf(
        verbs,
        "report",
        cmd_report,
        help="table: scenario, fault, delivered / total, overhead",
        description="Robot failures in-process (the paper's area, N=10 and 20) against the "
        "fault-free run; --dds adds real runs over DDS: an agent process "
        "SIGKILLed mid-run, and (as root, with nftables) 20 % packet loss on "
        "three simulated hosts.",
    )
    r.add_argument("--quick", action="store_true", help="one small scenario (a few seconds)")
    r.add_argument("--dds", action="store_true", help="also run the DDS fault runs (about a minute)")
    r.add_argument("--seed", type=at_least(0), default=1, help="which robots fail (seeded draw)")
    r.add_argument("--out", help="also write the table (markdown) to this file")
    r.add_argument("--json", action="store_true", help="print the rows as JSON")
    add_workers(r)
    p.set_defaults(func=lambda args: (p.print_help(), 2)[1], prog=p.prog)


def cmd_report(args: argparse.Namespace) -> int:
    if args.out and not Path(args.out).resolve().parent.is_dir():
        raise UsageError(f"--out {args.out}: directory {Path(args.out).parent} does not exist")
    t0 = time.monotonic()
    with executor(args) as ex:
        rows = in_process_rows(ex, args.quick, args.seed, args.progress)
    if args.dds:
        rows += dds_rows()
    elapsed = time.monotonic() - t0
    if args.json:
        print(json.dumps([dict(zip(HEADER, r.cells())) for r in rows], indent=1))
    else:
        print(markdown(rows))
        print(f"\n({len(rows)} runs, {elapsed:.1f} s)")
    if args.out:
        Path(args.out).write_text("# Fault report\n\n" + markdown(rows) + "\n")
    return 0


# ----------------------------------------------------------------------------- DDS runs


def _ost_up(timeout: int = 300, **settings: Any) -> tuple[dict | None, str, float]:
    """A DDS run (``ost up``) with these settings: its result, what it said, its wall time."""
    from ost_ros.commands.up import run_up

    t = time.monotonic()
    _code, out, err = run_up({**settings, "json": True, "timeout": timeout})
    try:
        return json.loads(out), err, time.monotonic() - t
    except ValueError:
        return None, err, time.monotonic() - t


def _stamp(text: str, pattern: str) -> float | None:
    m = re.search(r"\[(\d+\.\d+)\] [^\n]*" + pattern, text)
    return float(m.group(1)) if m else None


def dds_rows() -> list[FaultRow]:
    name = "DDS: N=4 M=8 30×12 nmax=3"
    scenario = generate_scenario(4, 8, 1, Grid(30, 12), 3)
    rows: list[FaultRow] = []
    with tempfile.TemporaryDirectory(prefix="ost_faults_") as tmp:
        path = Path(tmp) / "s.yaml"
        path.write_text(dump_scenario(scenario))
        base, err, wall0 = _ost_up(scenario=str(path), run_dir=f"{tmp}/base")
        if base is None:
            return [
                FaultRow(
                    name,
                    "none",
                    0,
                    len(scenario.objects),
                    None,
                    None,
                    "fault-free DDS run failed: " + err.strip().splitlines()[-1],
                )
            ]
        rows.append(
            FaultRow(
                name,
                "none",
                _delivered(base),
                len(base["objects"]),
                base["makespan"],
                base["makespan"],
                f"wall {wall0:.1f} s",
            )
        )
        got, err, wall = _ost_up(scenario=str(path), kill_agent=["2:40"], run_dir=f"{tmp}/kill")
        if got is None:
            rows.append(
                FaultRow(
                    name,
                    "agent 2 SIGKILL at step 40",
                    0,
                    len(scenario.objects),
                    None,
                    base["makespan"],
                    "run failed: " + err.strip().splitlines()[-1],
                )
            )
        else:
            failures = {f["agent"]: f["step"] for f in got["failures"]}
            ref = simulate(scenario, "ccp", CoordinationPolicy(ci=1), failures=failures).to_dict()
            same = all(got[k] == ref[k] for k in ("makespan", "objects", "agents", "schedule"))
            world = (Path(tmp) / "kill" / "world.log").read_text()
            agent = (Path(tmp) / "kill" / "agent_2.log").read_text()
            died, seen = _stamp(agent, "die_at_step"), _stamp(world, "agent 2 lost")
            detect = f"detected after {seen - died:.2f} s; " if died and seen else ""
            rows.append(
                FaultRow(
                    name,
                    "agent 2 SIGKILL at step 40",
                    _delivered(got),
                    len(got["objects"]),
                    got["makespan"],
                    base["makespan"],
                    f"{detect}failed in step {failures.get(2)}; = ost sim --fail: "
                    f"{'yes' if same else 'NO'}; wall {wall:.1f} s",
                )
            )
        if os.geteuid() == 0 and shutil.which("nft"):
            got, err, wall = _ost_up(scenario=str(path), hosts=3, loss=20, run_dir=f"{tmp}/loss")
            fault = "20 % packet loss, 3 simulated hosts"
            if got is None:
                rows.append(
                    FaultRow(
                        name,
                        fault,
                        0,
                        len(scenario.objects),
                        None,
                        base["makespan"],
                        "run failed: " + err.strip().splitlines()[-1],
                    )
                )
            else:
                same = got == base
                rows.append(
                    FaultRow(
                        name,
                        fault,
                        _delivered(got),
                        len(got["objects"]),
                        got["makespan"],
                        base["makespan"],
                        f"= fault-free result: {'yes' if same else 'NO'}; wall {wall:.1f} s vs {wall0:.1f} s",
                    )
                )
        else:
            rows.append(
                FaultRow(
                    name,
                    "20 % packet loss, 3 simulated hosts",
                    0,
                    len(scenario.objects),
                    None,
                    base["makespan"],
                    "not run: needs root and nft (nftables)",
                )
            )
    return rows


def _delivered(result: dict) -> int:
    return sum(o["delivered"] is not None for o in result["objects"])
