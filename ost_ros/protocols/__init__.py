"""The protocol registry: every cooperation protocol the system runs, by name.

Each protocol is a sub-package exporting ``SPEC`` (a :class:`~ost_ros.protocols.base.ProtocolSpec`:
its agent factory, messages, states, options and capabilities). Everything that lists protocols
or checks what a protocol can do asks here: the ``ost`` verbs and their ``--help``, the agent
node's parameters, ``ost_up.sh``, the study, the plots, the engines. Adding a protocol is its
package plus one line in :data:`PACKAGES` (docs/architecture.md, "How to add a protocol").
"""

from __future__ import annotations

from collections.abc import Mapping
from importlib import import_module
from typing import Any, cast

from ost_ros.coordination import CoordinationPolicy
from ost_ros.messages import AgentMessage
from ost_ros.model import Scenario
from ost_ros.protocols.base import Capabilities, Option, ProtocolAgent, ProtocolError, ProtocolSpec
from ost_ros.team import TeamInfo

# The protocols' packages, in the order listings show them: one line each.
PACKAGES = (
    "ost_ros.protocols.ccp",
    "ost_ros.protocols.hcp",
    "ost_ros.protocols.ncp",
    "ost_ros.protocols.auction",
    "ost_ros.protocols.greedy",
)
REGISTRY: dict[str, ProtocolSpec] = {
    spec.name: spec for spec in (cast(ProtocolSpec, import_module(p).SPEC) for p in PACKAGES)
}

__all__ = [
    "REGISTRY",
    "Capabilities",
    "Option",
    "ProtocolAgent",
    "ProtocolError",
    "ProtocolSpec",
    "check",
    "get",
    "make_agents",
    "messages",
    "names",
    "option_default",
    "settings_from",
]


def names() -> tuple[str, ...]:
    return tuple(REGISTRY)


def messages() -> tuple[type[AgentMessage], ...]:
    """Every agent message kind the registered protocols broadcast (their specs' ``messages``),
    each once, in registry order: what the wire converts and a topic each over DDS."""
    return tuple(dict.fromkeys(m for spec in REGISTRY.values() for m in spec.messages))


def get(name: str) -> ProtocolSpec:
    """The spec of protocol ``name``; an unknown name is one clear error."""
    spec = REGISTRY.get(name)
    if spec is None:
        raise ProtocolError(f"unknown protocol {name!r} (choose from {', '.join(REGISTRY)})")
    return spec


def _able(flag: str) -> str:
    return " and ".join(s.name for s in REGISTRY.values() if getattr(s.capabilities, flag)) or "none"


def check(
    name: str,
    *,
    scenario: Scenario | None = None,
    policy: CoordinationPolicy | None = None,
    failures: bool = False,
    silence: bool = False,
) -> ProtocolSpec:
    """The spec of ``name`` if it can run what is asked, else a one-line :class:`ProtocolError`:
    the scenario's team (speeds, own sweeps), the coordination organisation, robot failures,
    a silenced negotiator."""
    spec = get(name)
    caps = spec.capabilities
    if policy is not None and policy.organisation not in caps.organisations:
        able = " and ".join(
            s.name for s in REGISTRY.values() if policy.organisation in s.capabilities.organisations
        )
        raise ProtocolError(f"the {policy.organisation} organisation is for {able} only (not {name})")
    if failures and not caps.recovers_failures:
        raise ProtocolError(
            f"protocol {name} does not recover from failures ({_able('recovers_failures')} do)"
        )
    if silence and spec.silence is None:
        raise ProtocolError(f"a silenced negotiator: protocol {name} does not negotiate")
    if scenario is not None:
        if any(a.sweep for a in scenario.agents) and not caps.own_sweeps:
            raise ProtocolError(
                f"{name} cannot run robots with their own sweeps (a negotiated "
                f"partition); {_able('own_sweeps')} can"
            )
        if scenario.heterogeneous and not caps.heterogeneous:
            raise ProtocolError(
                f"{name} runs unit-speed teams only (agent periods other than 1 "
                f"need {_able('heterogeneous').replace(' and ', ' or ')})"
            )
    return spec


def option_default(spec: ProtocolSpec, option: Option) -> Any:
    """An option's default: its settings field's."""
    return getattr(spec.default_settings(), option.field)


def settings_from(name: str, values: Mapping[str, Any]) -> Any:
    """Protocol ``name``'s settings from option values by option name (absent ones: defaults;
    options of other protocols are ignored); a bad value is one clear error."""
    spec = get(name)
    if spec.settings is None:
        return None
    given = {o.field: values[o.name] for o in spec.options if values.get(o.name) is not None}
    try:
        return spec.settings(**given)
    except ValueError as exc:
        flags = ", ".join(o.flag for o in spec.options if o.field in given)
        raise ProtocolError(f"{flags}: {exc}") from None


def make_agents(
    scenario: Scenario, name: str, policy: CoordinationPolicy | None = None, settings: Any = None
) -> list[ProtocolAgent]:
    """The team's agents, one per robot of the scenario, in id order."""
    policy = policy or CoordinationPolicy()
    spec = check(name, scenario=scenario, policy=policy)
    team = TeamInfo.from_scenario(scenario)
    settings = spec.default_settings() if settings is None else settings
    return [spec.make_agent(a.id, team, policy, settings) for a in scenario.agents]
