"""ost_up.sh's preparation in one process (world_node.prepare): the same steps as ``ost
protocols check``, ``ost generate`` and ``ost keys make``, the team's ids on one line, and every
error one line with exit code 2."""

import pytest
import yaml

from ost_msgs_py.auth import load_team
from ost_ros.cli import main as ost
from ost_ros.scenario import load_scenario
from world_node.prepare import main as prepare


def test_generate_ids_and_keys_as_the_ost_verbs_make_them(tmp_path, capsys):
    code = prepare(
        ["--protocol", "ccp", "--generate", str(tmp_path / "s.yaml"), "--agents", "4", "--objects", "6"]
        + ["--seed", "2", "--width", "30", "--height", "12", "--nmax", "3", "--keys", str(tmp_path / "keys")]
    )
    assert code == 0
    assert capsys.readouterr().out == "0 1 2 3\n"
    ost(
        [
            "generate",
            "--agents",
            "4",
            "--objects",
            "6",
            "--seed",
            "2",
            "--width",
            "30",
            "--height",
            "12",
            "--nmax",
            "3",
        ]
    )
    assert (tmp_path / "s.yaml").read_text() == capsys.readouterr().out  # the same scenario
    team = load_team(tmp_path / "keys")
    assert sorted(team.keys) == [-1, 0, 1, 2, 3]  # the world and every agent


def test_a_team_replaces_the_scenarios(tmp_path, capsys):
    ost(
        [
            "generate",
            "--agents",
            "3",
            "--objects",
            "4",
            "--seed",
            "1",
            "--nmax",
            "3",
            "-o",
            str(tmp_path / "s.yaml"),
        ]
    )
    assert prepare(["--protocol", "hcp", "--scenario", str(tmp_path / "s.yaml"), "--team", "5"]) == 0
    assert capsys.readouterr().out.split() == ["0", "1", "2", "3", "4"]
    assert len(load_scenario(tmp_path / "s.yaml").agents) == 3  # the file is untouched


@pytest.mark.parametrize(
    ("args", "text"),
    [
        (["--protocol", "bogus"], "ost_up: error: --protocol bogus: unknown protocol 'bogus'"),
        (["--protocol", "hcp", "--coordination", "coordinator"], "--protocol hcp: the coordinator"),
        (["--protocol", "ccp", "--scenario", "{missing}"], "ost_up: error: "),
        (["--protocol", "ccp", "--scenario", "{bad}"], "invalid YAML at line"),
        (
            [
                "--protocol",
                "ccp",
                "--generate",
                "{out}",
                "--agents",
                "2",
                "--objects",
                "2",
                "--seed",
                "1",
                "--width",
                "0",
            ],
            "ost generate: error: ",
        ),
    ],
)
def test_errors_are_one_line_and_exit_2(tmp_path, capsys, args, text):
    (tmp_path / "bad.yaml").write_text("grid: {width: 3\nobjects: [")
    paths = {
        "missing": str(tmp_path / "none.yaml"),
        "bad": str(tmp_path / "bad.yaml"),
        "out": str(tmp_path / "o.yaml"),
    }
    assert prepare([a.format(**paths) for a in args]) == 2
    err = capsys.readouterr()
    assert text in err.err and len(err.err.strip().splitlines()) == 1 and not err.out


def test_protocol_alone_only_checks(tmp_path, capsys):
    assert prepare(["--protocol", "ncp", "--silence"]) == 0
    assert capsys.readouterr() == ("", "")
    assert list(tmp_path.iterdir()) == []


def test_yaml_loads_as_pyyaml_safe_load(tmp_path):
    from ost_ros.yamlload import safe_load

    ost(
        [
            "generate",
            "--agents",
            "3",
            "--objects",
            "5",
            "--seed",
            "4",
            "--nmax",
            "3",
            "-o",
            str(tmp_path / "s.yaml"),
        ]
    )
    text = (tmp_path / "s.yaml").read_text()
    assert safe_load(text) == yaml.safe_load(text)
    with pytest.raises(yaml.YAMLError):
        safe_load("a: !!python/object/apply:os.system ['true']")
