"""The lockstep runtimes wired without DDS: the world's and every agent's runtime exchanging
every message through the codec, as the nodes do over DDS (tests/runtime, and any test that
needs a protocol's run as the nodes would make it)."""

from agent_node.runtime import AgentRuntime
from ost_msgs_py import codec
from ost_msgs_py.runtime import Acted, AgentReport, RunEnd, StepMessages
from ost_ros.protocols import make_agents
from world_node.runtime import WorldRuntime


def wire(msg):
    return codec.decode(codec.encode(msg))


def run(scenario, protocol, policy, lookahead, skipping, kill=None):
    """``kill`` = {agent: step}: the agent's process is gone from the first tick at or after
    that step (with skipping, the world may be past it: then it fails later, as over DDS)."""
    ids = tuple(a.id for a in scenario.agents)
    rts = {a.id: AgentRuntime(a, ids, lookahead) for a in make_agents(scenario, protocol, policy)}
    world = WorldRuntime(scenario, skipping=skipping, protocol=protocol)
    nxt = world.start()
    kill = dict(kill or {})
    while True:
        for a, t in list(kill.items()):
            if not isinstance(nxt, RunEnd) and world.world.t >= t:
                del rts[a], kill[a]
                assert world.fail(a) is None  # the survivors still have to act
        for r in rts.values():
            if isinstance(nxt, RunEnd):
                r.accept_end(wire(nxt))
            else:
                r.accept_tick(wire(next(k for k in nxt if k.observation.agent == r.me)))
        out = [m for r in rts.values() for m in r.progress()]
        for b in (m for m in out if isinstance(m, StepMessages)):
            for r in rts.values():
                r.accept_batch(wire(b))
        for m in out:
            if isinstance(m, Acted):
                world.accept_acted(wire(m))
            elif isinstance(m, AgentReport):
                world.accept_report(wire(m))
        if isinstance(nxt, RunEnd):
            return world.result(), world
        nxt = world.advance()
