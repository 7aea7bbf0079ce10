"""The reference engine: the world and N agents stepped in lockstep, messages of a step delivered
to everyone within that step (the same semantics the ROS lockstep barrier provides).

Step t: every agent acts on its observation (search, motion) → all messages of the step are
exchanged → every agent's comm module runs → the world applies all actions at once → t+1.

Robot failures (``failures = {agent: step}``): from that step on the agent neither acts nor
sends; the world's :class:`AgentLost` notice joins the inbox of that step, after every agent's
messages — exactly where the ROS world node puts it (``Tick.failed``).
"""

from __future__ import annotations

from collections.abc import Callable

from ost_ros.engines.common import finish_result, step_limit
from ost_ros.messages import Action, AgentLost, AgentMessage
from ost_ros.model import Scenario
from ost_ros.protocols.base import ProtocolAgent
from ost_ros.result import RunResult
from ost_ros.world import World

StepHook = Callable[[World, list[Action]], None]


def run_steps(
    scenario: Scenario,
    agents: list[ProtocolAgent],
    max_steps: int | None = None,
    on_step: StepHook | None = None,
    failures: dict[int, int] | None = None,
) -> RunResult:
    """Step ``agents`` through the scenario to completion (or the step limit)."""
    failures = failures or {}
    world = World(scenario)
    limit = max_steps if max_steps is not None else step_limit(scenario, len(failures))
    messages = 0
    live = list(agents)
    while not world.done and world.t < limit:
        t = world.t
        lost = sorted(ag.id for ag in live if failures.get(ag.id) == t)
        live = [ag for ag in live if ag.id not in lost]
        actions = [ag.act(world.observe(ag.id)) for ag in live]
        inbox: list[AgentMessage] = [m for ag in live for m in ag.outbox()]
        messages += len(inbox)
        for a in lost:
            world.fail(a)
        inbox += [AgentLost(a, t, world.dropped_by(a)) for a in lost]
        for ag in live:
            ag.communicate(t, inbox)
        world.apply(actions)
        if on_step is not None:
            on_step(world, actions)
    return finish_result(world, agents, messages)
