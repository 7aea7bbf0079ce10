"""The protocol registry: one place lists the protocols and what each can run; an unknown name or
an impossible combination is one clear error everywhere; and a protocol added to the registry
with one line is at once a choice of the CLI, the engines, the lockstep runtime and the study."""

import contextlib
import dataclasses
import io
import json
import re
import subprocess
import sys

import pytest

from ost_msgs_py.wire import round_trip
from ost_ros import protocols
from ost_ros.cli import main
from ost_ros.coordination import CoordinationPolicy
from ost_ros.engines import simulate
from ost_ros.lockstep.inprocess import run_lockstep as lockstep_run
from ost_ros.messages import AgentMessage
from ost_ros.model import Grid
from ost_ros.protocols.base import ProtocolAgent
from ost_ros.scenario import dump_scenario, generate_scenario
from ost_ros.study.design import compared

INTERFACE = [m for m in dir(ProtocolAgent) if not m.startswith("_")]


def test_names_and_specs():
    assert protocols.names()[:2] == ("ccp", "hcp")  # the paper's two first, then the others
    assert len(set(protocols.names())) == len(protocols.names())
    for name, spec in protocols.REGISTRY.items():
        assert spec.name == name and spec.title and spec.states and spec.messages
        assert "SEARCHING" in spec.states and "FINISH" in spec.states  # the world reads these
        # the analytic engine needs the one comm module speaking for the team
        assert spec.capabilities.team_knowledge == (spec.team_comm is not None)


def test_the_message_table_is_the_specs():
    kinds = protocols.messages()
    assert set(kinds) == {m for spec in protocols.REGISTRY.values() for m in spec.messages}
    assert len(kinds) == len(set(kinds)) and all(issubclass(m, AgentMessage) for m in kinds)
    assert len({m.TYPE for m in kinds}) == len(kinds)  # a topic each


@pytest.mark.parametrize("name", protocols.names())
def test_every_agent_has_the_whole_interface(name):
    agents = protocols.make_agents(generate_scenario(2, 3, 1, Grid(12, 6), 2), name)
    for ag in agents:
        missing = [m for m in INTERFACE if not hasattr(ag, m)]
        assert missing == [] and ag.protocol == name


def test_unknown_name_is_one_clear_error_everywhere(tmp_path):
    choices = ", ".join(protocols.names())
    with pytest.raises(
        protocols.ProtocolError, match=re.escape(f"unknown protocol 'lottery' (choose from {choices})")
    ):
        protocols.get("lottery")
    s = generate_scenario(2, 2, 1, Grid(12, 6), 2)
    with pytest.raises(ValueError, match="unknown protocol 'lottery'"):
        simulate(s, "lottery")
    path = tmp_path / "s.yaml"
    path.write_text(dump_scenario(s))
    for argv in (["sim", str(path), "--protocol", "lottery"], ["protocols", "check", "lottery"]):
        r = subprocess.run([sys.executable, "-m", "ost_ros", *argv], capture_output=True, text=True)
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1
        assert "lottery" in r.stderr and "Traceback" not in r.stderr


@pytest.mark.parametrize(
    "name, what, text",
    [
        (
            "hcp",
            dict(policy=CoordinationPolicy(organisation="coordinator")),
            "coordinator organisation is for ccp only",
        ),
        ("hcp", dict(silence=True), "does not negotiate"),
    ],
)
def test_capabilities_are_checked(name, what, text):
    with pytest.raises(protocols.ProtocolError, match=re.escape(text)):
        protocols.check(name, **what)


def test_settings_from_options():
    assert protocols.settings_from("ccp", {"ncp_delta": 0.5}).planner == "paper"  # not its option
    assert protocols.settings_from("ccp", {"planner": "improved"}).planner == "improved"
    with pytest.raises(protocols.ProtocolError, match="--planner: planner must be one of paper, improved"):
        protocols.settings_from("ccp", {"planner": "best"})
    assert protocols.settings_from("ncp", {"ncp_delta": 0.5}).delta == 0.5
    with pytest.raises(protocols.ProtocolError, match="--ncp-timeout: NCP time-out"):
        protocols.settings_from("ncp", {"ncp_timeout": 0})


@pytest.fixture
def added(monkeypatch):
    """A protocol added with one registry entry: CCP's agents under another name."""
    base = protocols.REGISTRY["ccp"]

    def make_agent(agent_id, team, policy, settings=None):
        ag = base.make_agent(agent_id, team, policy, settings)
        ag.protocol = "twin"
        return ag

    spec = dataclasses.replace(base, name="twin", label="a twin of CCP", make_agent=make_agent)
    monkeypatch.setitem(protocols.REGISTRY, "twin", spec)
    return spec


def test_one_registry_line_reaches_cli_engines_runtime_and_study(added, tmp_path):
    s = generate_scenario(4, 6, 2, Grid(30, 12), 3)
    policy = CoordinationPolicy(ci=2)
    want = simulate(s, "ccp", policy).to_dict()
    for engine in ("step", "event"):
        got = simulate(s, "twin", policy, engine=engine).to_dict()
        assert got.pop("protocol") == "twin" and got == {k: v for k, v in want.items() if k != "protocol"}
    got, _ = lockstep_run(s, "twin", policy, 64, True, carry=round_trip)
    assert got.protocol == "twin" and got.makespan == want["makespan"]
    path = tmp_path / "s.yaml"
    path.write_text(dump_scenario(s))
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["sim", str(path), "--protocol", "twin", "--ci", "2", "--json"]) == 0
    assert json.loads(out.getvalue())["makespan"] == want["makespan"]
    assert "TWIN CI=1" in [v.label for v in compared()]
