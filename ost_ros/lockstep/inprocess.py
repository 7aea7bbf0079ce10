"""The lockstep runtimes wired in one process, without DDS: the world's runtime and every agent's,
exchanging the messages the nodes exchange, in the order they do. The same run as over DDS (and
as ``ost sim``), with the transport's figures (round trips, steps skipped on the agents' plans) —
for tests, benchmarks, and for checking a new protocol's planner before starting processes.

``carry`` is how a message reaches its receiver: by default the dataclass itself (this module is
ROS-free); ``carry=ost_msgs_py.wire.round_trip`` sends every message through its ``ost_msgs``
interface and back, exactly as the nodes do — what the tests run, so a new message's interface
is checked too.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from ost_ros.coordination import CoordinationPolicy
from ost_ros.lockstep.agent import LOOKAHEAD, AgentRuntime
from ost_ros.lockstep.messages import Acted, AgentReport, Ready, RunEnd, RunInfo, Sample
from ost_ros.lockstep.world import WorldRuntime
from ost_ros.model import Scenario
from ost_ros.protocols import make_agents
from ost_ros.result import RunResult
from ost_ros.scenario import dump_scenario


def same(msg: Any) -> Any:
    """A message handed over as it is (no transport)."""
    return msg


def run_lockstep(
    scenario: Scenario,
    protocol: str,
    policy: CoordinationPolicy,
    lookahead: int = LOOKAHEAD,
    skipping: bool = True,
    kill: dict[int, int] | None = None,
    settings: Any = None,
    tap: Callable[[Any], None] | None = None,
    carry: Callable[[Any], Any] = same,
) -> tuple[RunResult, WorldRuntime]:
    """The run and the world's runtime (its figures). ``kill`` = {agent: step}: the agent's
    process is gone from the first tick at or after that step (with skipping, the world may be
    past it: then it fails later, as over DDS). ``tap(message)`` sees every message the world
    sends or takes, in the order it does — what a recorder of the run would hold. ``carry``: how
    each message travels (the module docstring)."""
    ids = tuple(a.id for a in scenario.agents)
    rts = {a.id: AgentRuntime(a, ids, lookahead) for a in make_agents(scenario, protocol, policy, settings)}
    world = WorldRuntime(scenario, skipping=skipping, protocol=protocol, organisation=policy.organisation)
    see = tap or (lambda _msg: None)
    see(carry(RunInfo(world.run, dump_scenario(scenario), "", skipping, 0)))
    for a in ids:
        see(carry(Ready(a, protocol, "", policy.organisation)))
    nxt: list[Any] | RunEnd = world.start()
    kill = dict(kill or {})
    while True:
        for a, t in list(kill.items()):
            if not isinstance(nxt, RunEnd) and world.world.t >= t:
                del rts[a], kill[a]
                assert world.fail(a) is None  # the survivors still have to act
        for m in [nxt] if isinstance(nxt, RunEnd) else nxt:
            see(carry(m))
        for r in rts.values():
            if isinstance(nxt, RunEnd):
                r.accept_end(carry(nxt))
            else:
                r.accept_tick(carry(next(k for k in nxt if k.observation.agent == r.me)))
        out = [m for r in rts.values() for m in r.progress()]
        for b in (m for m in out if isinstance(m, Sample)):
            for r in rts.values():
                r.accept_sample(carry(b))
        for m in out:
            if isinstance(m, Acted | AgentReport):
                see(carry(m))
            if isinstance(m, Acted):
                world.accept_acted(carry(m))
            elif isinstance(m, AgentReport):
                world.accept_report(carry(m))
        if isinstance(nxt, RunEnd):
            return world.result(), world
        nxt = world.advance()
