"""Running real DDS processes from tests: bring-up through ost_up.sh, direct node processes with
an explicit ROS_DOMAIN_ID, and always a teardown (SIGTERM, then SIGKILL) of what was started."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent
UP = REPO / "bringup_scripts" / "ost_up.sh"


PROFILE = REPO / "ost_ros" / "dds" / "fastdds_localhost_udp.xml"


def ros_env(domain: int) -> dict[str, str]:
    """The test's own domain, and DDS on loopback only, as bringup_scripts/dds_env.sh sets it."""
    env = dict(os.environ)
    env["ROS_DOMAIN_ID"] = str(domain)
    profile = os.environ.get("FASTRTPS_DEFAULT_PROFILES_FILE") or str(PROFILE)
    env["FASTRTPS_DEFAULT_PROFILES_FILE"] = profile
    # Our profile keeps everything on loopback; a user's own profile gets the LOCALHOST range.
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SUBNET" if Path(profile) == PROFILE else "LOCALHOST"
    env["OST_VENV"] = str(BIN.parent)
    return env


def free_domain() -> int:
    """A domain id no other test run on this machine holds (lock directories, as ost_up.sh)."""
    root = Path("/tmp/ost_domain_locks")
    root.mkdir(exist_ok=True)
    start = os.getpid() % 90
    for k in range(90):
        d = (start + k) % 90 + 10
        lock = root / str(d)
        try:
            lock.mkdir()
        except FileExistsError:
            owner = (lock / "pid").read_text().strip() if (lock / "pid").exists() else ""
            if owner.isdigit() and not Path(f"/proc/{owner}").exists():
                (lock / "pid").unlink(missing_ok=True)
                lock.rmdir()
                lock.mkdir()
            else:
                continue
        (lock / "pid").write_text(str(os.getpid()))
        return d
    raise RuntimeError("no free ROS_DOMAIN_ID in 10..99")


def release_domain(domain: int) -> None:
    lock = Path("/tmp/ost_domain_locks") / str(domain)
    (lock / "pid").unlink(missing_ok=True)
    with contextlib.suppress(OSError):
        lock.rmdir()


def ost_up(
    *args: str, timeout: float = 240, during: Callable[[], None] | None = None
) -> subprocess.CompletedProcess:
    """Run ost_up.sh (it picks its own free domain) and return its completed process; ``during``
    is called while it runs (a fault the test injects). On a time-out the whole process group is
    ended (ost_up.sh's own teardown first), never orphaned."""
    env = dict(os.environ)
    env.pop("ROS_DOMAIN_ID", None)
    env["OST_VENV"] = str(BIN.parent)
    p = subprocess.Popen(
        ["bash", str(UP), *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        start_new_session=True,
    )
    t0 = time.monotonic()
    try:
        if during is not None:
            try:
                during()
            except BaseException:
                os.killpg(p.pid, signal.SIGTERM)
                raise
        out, err = p.communicate(timeout=max(1.0, timeout - (time.monotonic() - t0)))
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGTERM)  # ost_up.sh tears its nodes down on TERM
        try:
            out, err = p.communicate(timeout=15)
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, signal.SIGKILL)
            out, err = p.communicate()
        raise AssertionError(
            f"ost_up.sh {' '.join(args)} timed out after {timeout} s:\n{err[-3000:]}"
        ) from None
    return subprocess.CompletedProcess(p.args, p.returncode, out, err)


def make_keys(run_dir: Path, scenario: Path) -> list[str]:
    """Key material for a run of ``scenario`` (as ost_up.sh makes it): the node arguments."""
    keys = run_dir / "keys"
    subprocess.run(
        [str(BIN / "ost"), "keys", "make", str(keys), "--scenario", str(scenario)],
        check=True,
        capture_output=True,
    )
    return ["-p", f"keys:={keys}"]


INSECURE = ["-p", "insecure:=true"]


def progress_step(path) -> int:
    """The step in the world's progress file (``step delivered objects``; -1 while there is none)."""
    try:
        return int(Path(path).read_text().split()[0])
    except (OSError, IndexError, ValueError):
        return -1


def kill_mid_run(
    run_dir: Path, victim: str, at_step: int, *args: str, timeout: float = 180
) -> subprocess.CompletedProcess:
    """Run ost_up.sh with ``args`` and SIGKILL the process ``victim`` (``world``, ``agent_3``,
    ...) once the world's progress file has reached ``at_step``; the completed ost_up.sh process."""
    env = dict(os.environ, OST_VENV=str(BIN.parent))
    env.pop("ROS_DOMAIN_ID", None)
    up = subprocess.Popen(
        ["bash", str(UP), *args, "--run-dir", str(run_dir)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        start_new_session=True,
    )
    try:
        deadline = time.monotonic() + 120
        while progress_step(run_dir / "progress") < at_step:
            assert time.monotonic() < deadline and up.poll() is None, up.stderr.read()[-2000:]
            time.sleep(0.02)
        os.kill(int((run_dir / f"{victim}.pid").read_text()), signal.SIGKILL)
        out, err = up.communicate(timeout=timeout)
    finally:
        if up.poll() is None:
            os.killpg(up.pid, signal.SIGTERM)
            up.wait(20)
    return subprocess.CompletedProcess(up.args, up.returncode, out, err)


class Processes:
    """Node processes of one test: started with logs in ``run_dir``, always torn down."""

    def __init__(self, run_dir: Path, domain: int):
        self.run_dir = run_dir
        self.domain = domain
        self.procs: dict[str, subprocess.Popen] = {}
        self.shm_before = set(os.listdir("/dev/shm"))

    def start(self, name: str, exe: str, *ros_args: str) -> subprocess.Popen:
        return self.run(name, [str(BIN / exe), "--ros-args", *ros_args])

    def run(self, name: str, argv: list[str], env: dict[str, str] | None = None) -> subprocess.Popen:
        """Any command, logged to ``<name>.log``, on the test's domain (or with ``env``)."""
        log = open(self.run_dir / f"{name}.log", "w")  # noqa: SIM115 - the process writes it
        p = subprocess.Popen(
            argv,
            stdout=log,
            stderr=subprocess.STDOUT,
            env=env or ros_env(self.domain),
            start_new_session=True,
        )
        self.procs[name] = p
        return p

    def log(self, name: str) -> str:
        return (self.run_dir / f"{name}.log").read_text()

    def wait_for(self, name: str, text: str, timeout: float = 30) -> None:
        end = time.monotonic() + timeout
        while text not in self.log(name):
            p = self.procs[name]
            assert p.poll() is None, f"{name} exited ({p.returncode}):\n{self.log(name)[-2000:]}"
            assert time.monotonic() < end, f"{name}: no '{text}' after {timeout} s:\n{self.log(name)[-2000:]}"
            time.sleep(0.05)

    def stop(self) -> None:
        for p in self.procs.values():
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
        end = time.monotonic() + 5
        for p in self.procs.values():
            try:
                p.wait(max(0.1, end - time.monotonic()))
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        for f in set(os.listdir("/dev/shm")) - self.shm_before:
            if f.startswith(("fastrtps_", "sem.fastrtps_", "fast_datasharing")):
                with contextlib.suppress(OSError):
                    os.unlink(f"/dev/shm/{f}")


WAIT_MATCHED = r"""
import sys, time, rclpy
topic, n, seconds = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
rclpy.init()
node = rclpy.create_node("wait_matched")
end = time.monotonic() + seconds
while node.count_subscribers(topic) < n and time.monotonic() < end:
    rclpy.spin_once(node, timeout_sec=0.05)
ok = node.count_subscribers(topic) >= n
node.destroy_node(); rclpy.shutdown()
sys.exit(0 if ok else 1)
"""


def wait_subscribers(domain: int, topic: str, n: int, seconds: float = 60) -> None:
    """Until ``topic`` has ``n`` subscribers in the graph (counted by a node of its own)."""
    run = subprocess.run(
        [sys.executable, "-c", WAIT_MATCHED, topic, str(n), str(seconds)],
        env=ros_env(domain),
        capture_output=True,
        text=True,
        timeout=seconds + 30,
    )
    assert run.returncode == 0, f"{topic}: fewer than {n} subscribers after {seconds} s {run.stderr[-500:]}"


def reference(scenario, protocol: str, policy, settings=None, failures=None) -> dict:
    """What ``ost sim --json`` prints for the scenario: the in-process result and its bound."""
    from ost_ros.bounds import lower_bound
    from ost_ros.engines import simulate

    expected = simulate(scenario, protocol, policy, settings=settings, failures=failures).to_dict()
    expected["lower_bound"] = lower_bound(scenario).value
    return expected


def result_json(stdout: str) -> dict:
    return json.loads(stdout)


def kept_its_promise(result: dict, scenario_objects: int, dead: tuple[int, ...] = ()) -> None:
    """What a realtime run promises: every object delivered by exactly the group every robot
    scheduled, 0 disagreements, a lag reported for every robot (but the ``dead``: no report)."""
    assert result["mode"] == "realtime" and result["completed"], result.get("error")
    assert result["disagreements"] == 0 and result["agreement"]
    assert len(result["objects"]) == scenario_objects
    for o in result["objects"]:
        assert o["delivered"] is not None
    if result["protocol"] == "hcp":  # no schedule: the groups its requesters staffed
        for o in result["objects"]:
            assert o["agents"] and len(set(o["agents"])) == len(o["agents"])
    else:
        groups = {e["object"]: e["agents"] for e in result["schedule"]}
        for o in result["objects"]:  # carried by exactly the group every robot scheduled
            assert sorted(o["agents"]) == sorted(groups[o["id"]])
    assert set(result["lag"]) == {str(a["id"]) for a in result["agents"] if a["id"] not in dead}
