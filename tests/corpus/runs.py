"""The behaviour corpus: ``ost`` commands whose every output byte is recorded.

A refactor must leave each of these outputs unchanged (``tests/test_corpus.py``). The commands
cover every protocol (CCP under each trigger, HCP, NCP, the auction, greedy dispatch), both
engines, the coordinator organisation, robot failures, heterogeneous teams, negotiated search
areas, the exact optimum, Algorithm Coordination alone, the fault report and both papers'
reproductions (``--quick``).

Scenario files are written by the corpus's own ``ost generate`` commands (their output is part
of the corpus), into a scratch folder named by ``{dir}`` in the arguments.

Re-record only when a change of behaviour is intended: ``python tests/corpus/record.py``.
"""

from __future__ import annotations

# name -> (size, grid, nmax, periods): the scenarios every run below uses
SCENARIOS: dict[str, tuple[tuple[int, int, int], tuple[int, int], int, str | None]] = {
    "small": ((4, 7, 1), (60, 24), 3, None),
    "mid": ((6, 12, 5), (36, 18), 4, None),
    "paper": ((10, 20, 1), (500, 200), 10, None),
    "crowd": ((8, 15, 3), (100, 40), 5, None),
    "hetero": ((4, 10, 2), (80, 40), 3, "1,1,2,3"),
}


def generate_commands() -> list[tuple[str, list[str]]]:
    out = []
    for name, ((n, m, seed), (w, h), nmax, periods) in SCENARIOS.items():
        argv = [
            "generate",
            "--agents",
            str(n),
            "--objects",
            str(m),
            "--seed",
            str(seed),
            "--width",
            str(w),
            "--height",
            str(h),
            "--nmax",
            str(nmax),
        ]
        if periods:
            argv += ["--periods", periods]
        out.append((f"generate-{name}", argv + ["-o", "{dir}/" + name + ".yaml"]))
    return out


def sim_commands() -> list[tuple[str, list[str]]]:
    out: list[tuple[str, list[str]]] = []

    def sim(label: str, scenario: str, *flags: str, engines=("step", "event")) -> None:
        for engine in engines:
            out.append(
                (
                    f"sim-{scenario}-{label}-{engine}",
                    ["sim", "{dir}/" + scenario + ".yaml", *flags, "--engine", engine, "--json"],
                )
            )

    for sc in ("small", "mid", "paper", "crowd"):
        sim("ccp-ci1", sc, "--protocol", "ccp", "--ci", "1")
        sim("ccp-ciM", sc, "--protocol", "ccp", "--ci", "1000")
        sim("hcp", sc, "--protocol", "hcp")
        sim("ncp-ci1", sc, "--protocol", "ncp", "--ci", "1")
    for sc in ("small", "crowd", "hetero"):
        sim("ccp-interval", sc, "--protocol", "ccp", "--interval", "40")
        sim("ccp-area", sc, "--protocol", "ccp", "--area-fraction", "0.25")
        sim("ncp-ci3", sc, "--protocol", "ncp", "--ci", "3", "--ncp-delta", "0.7")
    sim("ccp-ci1", "hetero", "--protocol", "ccp", "--ci", "1")
    sim("ccp-ci4", "hetero", "--protocol", "ccp", "--ci", "4")
    sim("ccp-agents8", "mid", "--protocol", "ccp", "--ci", "2", "--agents", "8")
    sim("hcp-agents5", "crowd", "--protocol", "hcp", "--agents", "5")
    for sc in ("small", "crowd", "hetero"):
        sim(
            "coordinator",
            sc,
            "--protocol",
            "ccp",
            "--ci",
            "2",
            "--coordination",
            "coordinator",
            engines=("step",),
        )
    sim("fail-ccp", "crowd", "--protocol", "ccp", "--fail", "2:40", "--fail", "5:120", engines=("step",))
    sim("fail-ccp", "hetero", "--protocol", "ccp", "--ci", "2", "--fail", "1:60", engines=("step",))
    sim("fail-ccp", "paper", "--protocol", "ccp", "--fail", "3:500", engines=("step",))
    sim("fail-hcp", "crowd", "--protocol", "hcp", "--fail", "2:40", "--fail", "6:150", engines=("step",))
    sim("fail-hcp", "mid", "--protocol", "hcp", "--fail", "1:20", engines=("step",))
    sim("negotiated-ccp", "hetero", "--protocol", "ccp", "--partition", "negotiated")
    sim("negotiated-ncp", "hetero", "--protocol", "ncp", "--partition", "negotiated", engines=("event",))
    # the peers (recorded when they were added; they must not drift either)
    for sc in ("small", "crowd", "hetero"):
        sim("ccp-improved-ci1", sc, "--protocol", "ccp", "--ci", "1", "--planner", "improved")
        sim("auction", sc, "--protocol", "auction")
    sim("ccp-improved-ciM", "mid", "--protocol", "ccp", "--ci", "1000", "--planner", "improved")
    sim("fail-ncp", "crowd", "--protocol", "ncp", "--fail", "2:40", engines=("step",))
    sim("fail-auction", "crowd", "--protocol", "auction", "--fail", "2:40", engines=("step",))
    for sc in ("small", "crowd", "hetero"):
        sim("greedy", sc, "--protocol", "greedy")
    sim("fail-greedy", "crowd", "--protocol", "greedy", "--fail", "2:40", engines=("step",))
    sim(
        "fail-coordinator",
        "crowd",
        "--protocol",
        "ccp",
        "--coordination",
        "coordinator",
        "--fail",
        "0:40",
        engines=("step",),
    )
    # the text a user reads, not only the JSON
    out.append(("sim-small-ccp-text", ["sim", "{dir}/small.yaml", "--protocol", "ccp"]))
    out.append(("sim-crowd-hcp-text", ["sim", "{dir}/crowd.yaml", "--protocol", "hcp"]))
    return out


def other_commands() -> list[tuple[str, list[str]]]:
    return [
        ("optimal-small", ["optimal", "{dir}/small.yaml", "--json"]),
        ("schedule-state", ["schedule", "{dir}/state.json", "--json"]),
        ("schedule-state-improved", ["schedule", "{dir}/state.json", "--json", "--planner", "improved"]),
        ("partition-hetero", ["negotiate", "partition", "--scenario", "{dir}/hetero.yaml", "--json"]),
        (
            "negotiate-targets",
            ["negotiate", "run", "--task", "targets", "--robots", "3", "--targets", "6", "--json"],
        ),
        ("faults-quick", ["faults", "report", "--quick", "--json"]),
    ]


# A coordination state for ``ost schedule`` (written beside the scenarios).
STATE = {
    "agents": [
        {"id": 0, "cost": 0, "location": [0, 0]},
        {"id": 1, "cost": 5, "location": [9, 3]},
        {"id": 2, "cost": 2, "location": [4, 8]},
    ],
    "objects": [
        {"id": 0, "location": [3, 3], "destination": [8, 8], "required": 2},
        {"id": 1, "location": [7, 1], "destination": [0, 9], "required": 1},
        {"id": 2, "location": [5, 5], "destination": [5, 0], "required": 3},
    ],
}

# Directory outputs: every file but pictures; lines with wall times are left out of reports.
REPRODUCTIONS: list[tuple[str, list[str]]] = [
    ("reproduce-quick", ["reproduce", "--quick", "--out", "{out}"]),
    ("negotiate-reproduce-quick", ["negotiate", "reproduce", "--quick", "--out", "{out}"]),
]


def realtime_commands() -> list[tuple[str, list[str]]]:
    """Runs without a barrier (``ost sim --latency``): every protocol and planner, jitter, speed
    noise, stalls, failures, bases across a network, silences, joins and partitions."""
    out: list[tuple[str, list[str]]] = []

    def rt(label: str, scenario: str, *flags: str) -> None:
        out.append((f"rt-{scenario}-{label}", ["sim", "{dir}/" + scenario + ".yaml", *flags, "--json"]))

    for sc in ("small", "crowd"):
        rt("ccp-l0", sc, "--protocol", "ccp", "--latency", "0")
        rt("ccp-l5", sc, "--protocol", "ccp", "--latency", "5:5", "--latency-seed", "3")
        rt("hcp-l3", sc, "--protocol", "hcp", "--latency", "3:4", "--latency-seed", "1")
        rt("ncp-l2", sc, "--protocol", "ncp", "--latency", "2:3")
        rt("auction-l4", sc, "--protocol", "auction", "--latency", "4:4", "--latency-seed", "2")
        rt("greedy-l6", sc, "--protocol", "greedy", "--latency", "6:2")
        if sc == "small":  # (the improved planner at every robot's every coordination: seconds)
            rt("improved-l3", sc, "--protocol", "ccp", "--planner", "improved", "--latency", "3:3")
        rt("coordinator-l5", sc, "--protocol", "ccp", "--coordination", "coordinator", "--latency", "5:5")
    rt("ccp-jitter", "hetero", "--protocol", "ccp", "--ci", "2", "--latency", "8:8", "--speed-jitter", "0.5")
    rt("ccp-stall", "mid", "--protocol", "ccp", "--latency", "2:2", "--stall", "1:10:30", "--stall", "3:40:5")
    rt("ccp-fail", "crowd", "--protocol", "ccp", "--latency", "4:4", "--fail", "2:40", "--fail", "5:120")
    rt("hcp-fail", "crowd", "--protocol", "hcp", "--latency", "2:2", "--fail", "2:40")
    rt("ncp-fail", "crowd", "--protocol", "ncp", "--latency", "3:1", "--fail", "1:30")
    rt("auction-fail", "mid", "--protocol", "auction", "--latency", "3:3", "--fail", "0:25")
    rt("greedy-fail", "crowd", "--protocol", "greedy", "--latency", "5:0", "--fail", "3:50")
    rt(
        "improved-fail",
        "small",
        "--protocol",
        "ccp",
        "--planner",
        "improved",
        "--latency",
        "2:6",
        "--fail",
        "2:60",
    )
    for proto in ("ccp", "hcp", "ncp", "auction", "greedy"):
        rt(f"{proto}-remote", "crowd", "--protocol", proto, "--latency", "2:2", "--base-delay", "1:2")
    rt(
        "improved-remote",
        "small",
        "--protocol",
        "ccp",
        "--planner",
        "improved",
        "--latency",
        "1:1",
        "--base-delay",
        "0.5:1",
    )
    rt(
        "ccp-remote-fail",
        "crowd",
        "--protocol",
        "ccp",
        "--latency",
        "3:3",
        "--base-delay",
        "2:1",
        "--fail",
        "1:70",
    )
    rt(
        "hcp-remote-fail",
        "crowd",
        "--protocol",
        "hcp",
        "--latency",
        "1:3",
        "--base-delay",
        "1:1",
        "--fail",
        "6:90",
    )
    for proto in ("ccp", "ncp", "auction", "greedy"):
        rt(
            f"{proto}-silence",
            "crowd",
            "--protocol",
            proto,
            "--latency",
            "3:3",
            "--silence",
            "2:30:60",
            "--silence",
            "4:80:5",
        )
        rt(f"{proto}-join", "crowd", "--protocol", proto, "--latency", "2:4", "--join", "5:60")
    rt(
        "hcp-silence",
        "crowd",
        "--protocol",
        "hcp",
        "--latency",
        "3:3",
        "--silence",
        "2:30:60",
        "--failure-timeout",
        "20",
    )
    rt(
        "improved-silence-join",
        "small",
        "--protocol",
        "ccp",
        "--planner",
        "improved",
        "--latency",
        "2:2",
        "--silence",
        "1:20:40",
        "--join",
        "3:90",
    )
    rt("ccp-split", "crowd", "--protocol", "ccp", "--latency", "2:2", "--split", "0,1,2/3,4,5,6,7:40:80")
    rt(
        "ccp-split-lost",
        "crowd",
        "--protocol",
        "ccp",
        "--latency",
        "2:2",
        "--split",
        "0,1,2,3/4,5,6,7:30:120",
        "--split-mode",
        "lost",
    )
    rt("ncp-split", "crowd", "--protocol", "ncp", "--latency", "1:3", "--split", "0,2,4,6/1,3,5,7:50:60")
    rt("hcp-split", "crowd", "--protocol", "hcp", "--latency", "2:1", "--split", "0,1/2,3,4,5,6,7:60:40")
    rt(
        "greedy-split-lost",
        "crowd",
        "--protocol",
        "greedy",
        "--latency",
        "2:2",
        "--split",
        "0,1,2,3/4,5,6,7:20:90",
        "--split-mode",
        "lost",
    )
    rt("ccp-paper", "paper", "--protocol", "ccp", "--latency", "5:5")
    rt(
        "ccp-everything",
        "crowd",
        "--protocol",
        "ccp",
        "--ci",
        "2",
        "--latency",
        "4:6",
        "--speed-jitter",
        "0.3",
        "--stall",
        "0:20:15",
        "--fail",
        "7:100",
        "--silence",
        "3:40:50",
        "--join",
        "5:70",
        "--split",
        "0,1,2/3,4,5,6,7:150:60",
        "--base-delay",
        "1:1",
    )
    out.append(("rt-small-ccp-text", ["sim", "{dir}/small.yaml", "--protocol", "ccp", "--latency", "3:3"]))
    return out


def commands() -> list[tuple[str, list[str]]]:
    return generate_commands() + sim_commands() + other_commands() + realtime_commands()
