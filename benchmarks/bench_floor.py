"""The DDS floor of a lockstep round trip on this machine, with plain rclpy (not a test).

    .venv/bin/python benchmarks/bench_floor.py --agents 10 20 50 --rounds 300
    .venv/bin/python benchmarks/bench_floor.py --agents 10 --executor spin_once single events

N+1 processes, none of our code: a world publishing one ~300 B string per agent on per-agent
topics, every agent answering one ~200 B string on a shared topic, the world waiting for all N
(``star``); and the same plus every agent publishing one ~200 B message per round on a shared
topic that every agent waits for (all N) before it answers (``all``: all-to-all). Same Fast DDS
profile (bringup_scripts/dds_env.sh: UDP on loopback), same QoS (reliable, keep-all, volatile)
as the lockstep. Bring-up: from the start of the N+1 processes to every endpoint matched (counted).

Executors: ``spin_once`` (``rclpy.spin_once(node)`` in a loop: a new wait set per call),
``single`` (one ``SingleThreadedExecutor``, ``spin_once`` in a loop), ``events`` (rclpy's
``EventsExecutor``). Prints one row per (N, pattern, executor): median and p90 round trip,
bring-up, and the machine's load. ``--json`` prints the rows as JSON (bench_ros.py reads them).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
EXECUTORS = ("spin_once", "single", "events")
PATTERNS = ("star", "all")
TICK = "t" * 300  # payloads of the sizes of a tick and of an answer
ANSWER = "a" * 200


# ---------------------------------------------------------------------- the two roles


def _qos():
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(
        history=HistoryPolicy.KEEP_ALL,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.VOLATILE,
    )


def _spinner(node, executor: str):
    """A function that handles what is ready (waiting at most ``timeout`` s)."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    if executor == "spin_once":
        return lambda timeout: rclpy.spin_once(node, timeout_sec=timeout)
    if executor == "single":
        ex = SingleThreadedExecutor()
    else:
        from rclpy.experimental import EventsExecutor

        ex = EventsExecutor()
    ex.add_node(node)
    return lambda timeout: ex.spin_once(timeout_sec=timeout)


def world(n: int, rounds: int, pattern: str, executor: str, t0: float) -> None:
    import rclpy
    from rclpy.duration import Duration
    from std_msgs.msg import String

    rclpy.init()
    node = rclpy.create_node("floor_world")
    q = _qos()
    ticks = [node.create_publisher(String, f"floor/tick_{i}", q) for i in range(n)]
    got: dict[int, set[int]] = {}
    node.create_subscription(
        String, "floor/acted", lambda m: got.setdefault(int(m.data[:8]), set()).add(int(m.data[8:16])), q
    )
    ready = node.create_subscription(
        String, "floor/ready", lambda m: got.setdefault(-1, set()).add(int(m.data)), q
    )
    spin = _spinner(node, executor)
    while len(got.get(-1, ())) < n or any(p.get_subscription_count() < 1 for p in ticks):
        spin(0.05)
    bring_up = time.time() - t0
    del ready
    times = []
    for r in range(rounds):
        start = time.perf_counter()
        for p in ticks:
            p.publish(String(data=f"{r:08d}" + TICK))
        while len(got.get(r, ())) < n:
            spin(1.0)
        times.append(time.perf_counter() - start)
        got.pop(r)
    for p in ticks:
        p.publish(String(data=f"{-1:08d}"))  # the end
    for p in ticks:
        p.wait_for_all_acked(Duration(seconds=10))  # delivered before this process goes
    print(json.dumps({"bring_up": bring_up, "times": times}), flush=True)
    os._exit(0)  # no teardown: rcl now and then hangs in destroy_node (ost_ros/node/run.py)


def agent(i: int, n: int, pattern: str, executor: str) -> None:
    import rclpy
    from std_msgs.msg import String

    rclpy.init()
    node = rclpy.create_node(f"floor_agent_{i}")
    q = _qos()
    acted = node.create_publisher(String, "floor/acted", q)
    ready = node.create_publisher(String, "floor/ready", q)
    state = {"tick": None, "done": False}
    steps: dict[int, int] = {}

    def on_tick(m):
        r = int(m.data[:8])
        if r < 0:
            state["done"] = True
            return
        state["tick"] = r
        if pattern == "all":
            step.publish(String(data=f"{r:08d}{i:08d}" + ANSWER))
        answer()

    def on_step(m):
        r = int(m.data[:8])
        steps[r] = steps.get(r, 0) + 1
        answer()

    def answer():
        r = state["tick"]
        if r is None or (pattern == "all" and steps.get(r, 0) < n):
            return
        acted.publish(String(data=f"{r:08d}{i:08d}" + ANSWER))
        steps.pop(r, None)
        state["tick"] = None

    tick_sub = node.create_subscription(String, f"floor/tick_{i}", on_tick, q)
    step = node.create_publisher(String, "floor/step", q)
    step_sub = node.create_subscription(String, "floor/step", on_step, q)
    spin = _spinner(node, executor)

    def matched() -> bool:
        ok = acted.get_subscription_count() >= 1 and ready.get_subscription_count() >= 1
        if pattern == "all":
            ok = ok and step.get_subscription_count() >= n and step_sub.get_publisher_count() >= n
        return ok

    while not matched():
        spin(0.05)
    ready.publish(String(data=str(i)))
    # Until the end marker, or the world gone for 2 s (its end marker lost with it).
    gone_since = None
    while not state["done"]:
        spin(0.5)
        if tick_sub.get_publisher_count() == 0:
            gone_since = gone_since or time.monotonic()
            state["done"] = time.monotonic() - gone_since > 2.0
        else:
            gone_since = None
    os._exit(0)  # as the world


# ---------------------------------------------------------------------- the benchmark


def _env() -> dict[str, str]:
    out = subprocess.run(
        ["bash", "-c", f". {REPO}/bringup_scripts/dds_env.sh && env -0"], capture_output=True, check=True
    ).stdout
    env = dict(kv.split("=", 1) for kv in out.decode().split("\0") if "=" in kv)
    sys.path.insert(0, str(REPO / "tests/ros"))
    from dds_helpers import free_domain  # the lock directories ost_up.sh and the tests share

    env["ROS_DOMAIN_ID"] = str(free_domain())
    return env


def measure(n: int, rounds: int, pattern: str, executor: str) -> dict:
    """One configuration: N agents and a world, ``rounds`` round trips."""
    sys.path.insert(0, str(REPO / "tests/ros"))
    from dds_helpers import release_domain

    env = _env()
    me = [sys.executable, __file__, "--pattern-arg", pattern, "--executor-arg", executor, "-n", str(n)]
    t0 = time.time()
    load = os.getloadavg()[0]
    procs = [subprocess.Popen([*me, "--role", "agent", "--id", str(i)], env=env) for i in range(n)]
    w = subprocess.Popen(
        [*me, "--role", "world", "--rounds", str(rounds), "--t0", repr(t0)],
        env=env,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        out, _ = w.communicate(timeout=600 + rounds * n * 0.05)
        for p in procs:  # the measurement is in; agents leave on the end marker
            p.wait(timeout=30)
    finally:
        for p in [w, *procs]:
            if p.poll() is None:
                p.kill()
                p.wait()
        release_domain(int(env["ROS_DOMAIN_ID"]))
    d = json.loads(out.strip().splitlines()[-1])
    times = sorted(d["times"][min(10, rounds // 10) :])  # the first rounds settle the connections
    return {
        "N": n,
        "pattern": pattern,
        "executor": executor,
        "rounds": rounds,
        "median_ms": 1000 * statistics.median(times),
        "p90_ms": 1000 * times[int(0.9 * (len(times) - 1))],
        "bring_up_s": d["bring_up"],
        "load": load,
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--agents", type=int, nargs="+", default=[10, 20, 50])
    ap.add_argument("--rounds", type=int, default=300)
    ap.add_argument("--pattern", nargs="+", choices=PATTERNS, default=list(PATTERNS))
    ap.add_argument("--executor", nargs="+", choices=EXECUTORS, default=["spin_once", "events"])
    ap.add_argument("--json", action="store_true")
    # the roles (internal)
    ap.add_argument("--role", choices=("world", "agent"), help=argparse.SUPPRESS)
    ap.add_argument("--id", type=int, default=0, help=argparse.SUPPRESS)
    ap.add_argument("-n", type=int, default=0, help=argparse.SUPPRESS)
    ap.add_argument("--t0", type=float, default=0.0, help=argparse.SUPPRESS)
    ap.add_argument("--pattern-arg", default="star", help=argparse.SUPPRESS)
    ap.add_argument("--executor-arg", default="events", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.role == "world":
        world(a.n, a.rounds, a.pattern_arg, a.executor_arg, a.t0)
        return 0
    if a.role == "agent":
        agent(a.id, a.n, a.pattern_arg, a.executor_arg)
        return 0
    rows = []
    if not a.json:
        print("| N | pattern | executor | round trip median (p90) | bring-up | load (1 min) |")
        print("|---|---|---|---|---|---|")
    for n in a.agents:
        for pattern in a.pattern:
            for ex in a.executor:
                row = measure(n, a.rounds, pattern, ex)
                rows.append(row)
                if not a.json:
                    print(
                        f"| {n} | {pattern} | {ex} | {row['median_ms']:.1f} ms ({row['p90_ms']:.1f}) "
                        f"| {row['bring_up_s']:.1f} s | {row['load']:.2f} |",
                        flush=True,
                    )
    if a.json:
        print(json.dumps(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
