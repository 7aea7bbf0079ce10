"""The one run configuration: every bring-up (ost up, ost_up.sh, the launch file) and every node
derive their options and parameters from ost_ros.runconfig.SETTINGS."""

import pytest

from ost_ros import protocols, runconfig
from ost_ros.runconfig import AGENT, WATCH, WORLD, ConfigError, RunConfig


def test_every_protocol_option_is_a_setting_of_the_agent():
    for spec in protocols.REGISTRY.values():
        for opt in spec.options:
            s = runconfig.BY_NAME[opt.name]
            assert AGENT in s.nodes and s.option
            assert s.default == protocols.option_default(spec, opt)


def test_names_are_unique_and_flags_follow_them():
    names = [s.name for s in runconfig.SETTINGS]
    assert len(names) == len(set(names))
    for s in runconfig.options():
        assert s.cli == (s.flag or "--" + s.name.replace("_", "-"))
    assert runconfig.BY_NAME["event_skipping"].cli == "--no-skip"  # the flag users know


@pytest.mark.parametrize(
    ("given", "setting", "text"),
    [
        ({"ci": 0}, "ci", "must be at least 1, got 0"),
        ({"ci": "x"}, "ci", "invalid int 'x'"),
        ({"protocol": "bogus"}, "protocol", "'bogus' is not one of"),
        ({"area_fraction": 1.5}, "area_fraction", "must be at most 1"),
        ({"insecure": "maybe"}, "insecure", "expected true or false"),
        ({"kill_agent": ["3"]}, "kill_agent", "expected AGENT:STEP"),
        ({"ncp_delta": 2.0}, "protocol", "--ncp-delta"),
        ({"interval": 5, "area_fraction": 0.5}, "interval", "choose one trigger"),
        ({"nonsense": 1}, "nonsense", "unknown setting"),
    ],
)
def test_bad_values_name_their_setting(given, setting, text):
    with pytest.raises(ConfigError) as err:
        RunConfig.of(given)
    assert err.value.setting == setting and text in str(err.value)
    assert "\n" not in str(err.value)


def test_text_values_parse_as_a_launch_argument_gives_them():
    cfg = RunConfig.of({"ci": "3", "insecure": "true", "area_fraction": "0.25", "kill_agent": "1:5, 2:9"})
    assert (cfg["ci"], cfg["insecure"], cfg["area_fraction"]) == (3, True, 0.25)
    assert cfg.kills() == {1: 5, 2: 9}


def test_parameters_of_each_role_are_its_settings():
    cfg = RunConfig.of({"protocol": "ncp", "ncp_delta": 0.5, "kill_agent": ["2:40"], "record": "r.mcap"})
    for role in (WORLD, AGENT, WATCH):
        assert set(cfg.parameters(role)) == {s.name for s in runconfig.of_node(role)}
    agent = cfg.parameters(AGENT, agent_id=2)
    assert (agent["ncp_delta"], agent["die_at_step"], agent["observers"]) == (0.5, 40, 1)
    assert cfg.parameters(AGENT, agent_id=1)["die_at_step"] == -1
    assert cfg.parameters(WATCH)["record"] == "r.mcap"


def test_a_run_needs_a_scenario_and_checks_the_protocol():
    with pytest.raises(ConfigError, match="give --agents N --objects M"):
        RunConfig.of({"agents": 4}).check_run(is_root=True)
    with pytest.raises(ConfigError, match="excludes --objects"):
        RunConfig.of({"scenario": "s.yaml", "seed": 3}).check_run(is_root=True)
    with pytest.raises(ConfigError, match="coordinator organisation"):
        RunConfig.of({"agents": 2, "objects": 2, "protocol": "hcp", "coordination": "coordinator"}).check_run(
            True
        )
    with pytest.raises(ConfigError, match="need root"):
        RunConfig.of({"agents": 2, "objects": 2, "hosts": 3}).check_run(is_root=False)
    with pytest.raises(ConfigError, match="needs --hosts"):
        RunConfig.of({"agents": 2, "objects": 2, "loss": 20}).check_run(is_root=True)
    with pytest.raises(ConfigError, match="an option of ncp, not of ccp"):
        RunConfig.of({"agents": 2, "objects": 2, "ncp_delta": 0.5}).check_run(is_root=True)
    RunConfig.of({"agents": 2, "objects": 2}).check_run(is_root=False)


def test_the_policy_and_settings_the_agents_run():
    cfg = RunConfig.of({"ci": 4, "coordination": "coordinator", "planner": "improved"})
    assert (cfg.policy().ci, cfg.policy().organisation) == (4, "coordinator")
    assert cfg.protocol_settings().planner == "improved"
    assert RunConfig.of({"interval": 50}).policy().interval == 50
