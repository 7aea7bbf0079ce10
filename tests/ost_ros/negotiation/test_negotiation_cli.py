"""``ost negotiate``: one-line errors with exit code 2, and working runs (as subprocesses)."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]


def ost(*args, timeout=120):
    return subprocess.run(
        [sys.executable, "-m", "ost_ros.cli", "negotiate", *args],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=timeout,
    )


@pytest.mark.parametrize(
    "args, msg",
    [
        (["run", "--delta", "1.2"], "must be in (0, 1)"),
        (["run", "--delta", "0"], "must be in (0, 1)"),
        (["run", "--robots", "0"], "at least one robot"),
        (["run", "--task", "blob"], "unknown task type"),
        (["run", "--polygon", "0,0;1,1;0,1;1,0"], "self-intersecting"),
        (["run", "--polygon", "0,0;1,1"], "at least 3"),
        (["run", "--polygon", "a,b;c"], "--polygon"),
        (["run", "--file", "/nonexistent/task.yaml"], "cannot read task file"),
        (["run", "--strategy", "coalitions"], "unknown strategy"),
        (["run", "--task", "targets", "--targets", "0"], "at least one target"),
        (["run", "--delta", "0.9,0.8,0.7", "--robots", "2"], "3 discount factors for 2 robots"),
        (["reproduce", "--out", "/tmp/x", "--runs", "0"], "--runs"),
        (["run", "--seed", "-1"], "--seed"),
        (["reproduce", "--out", "/tmp/x", "--seed", "-1"], "--seed"),
        (["run", "--task", "targets", "--drop-rule", "nearest"], "unknown drop rule"),
        (["run", "--stopping", "never"], "unknown stopping rule"),
    ],
)
def test_bad_input_is_one_line_exit_2(args, msg):
    p = ost(*args)
    assert p.returncode == 2, p.stderr
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1, p.stderr
    assert msg in lines[0] and "Traceback" not in p.stderr
    assert lines[0].startswith("ost negotiate")


def test_bad_task_files(tmp_path):
    bad_yaml = tmp_path / "bad.yaml"
    bad_yaml.write_text("task: [area\n")
    bad_json = tmp_path / "bad.json"
    bad_json.write_text("{not json")
    unknown = tmp_path / "unknown.yaml"
    unknown.write_text("task: area\ncolour: blue\n")
    not_map = tmp_path / "list.yaml"
    not_map.write_text("- 1\n- 2\n")
    for f, msg in (
        (bad_yaml, "not valid YAML"),
        (bad_json, "not valid JSON"),
        (unknown, "unknown key"),
        (not_map, "mapping"),
    ):
        p = ost("run", "--file", str(f))
        assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1, p.stderr
        assert msg in p.stderr


def test_run_targets_json():
    p = ost("run", "--task", "targets", "--robots", "3", "--targets", "6", "--seed", "4", "--json")
    assert p.returncode == 0, p.stderr
    out = json.loads(p.stdout)
    assert out["status"] == "agreed" and out["metrics"]["G"] == pytest.approx(6)
    assert sorted(j for r in out["robots"] for j in r["targets"]) == list(range(6))


def test_run_targets_beyond_the_exact_route_solver():
    """40 targets: routes of more than 12 points come from the bounded heuristic, said so."""
    p = ost("run", "--task", "targets", "--targets", "40", "--robots", "2")
    assert p.returncode == 0, p.stderr
    assert "nearest neighbour + 2-opt" in p.stdout and "Traceback" not in p.stderr


def test_task_file_with_negative_seed_is_refused(tmp_path):
    f = tmp_path / "task.yaml"
    f.write_text("task: targets\nseed: -3\n")
    p = ost("run", "--file", str(f))
    assert p.returncode == 2 and "seed must be 0 or more" in p.stderr


def test_run_area_from_file_with_nfz(tmp_path):
    f = tmp_path / "task.yaml"
    f.write_text(
        "task: area\n"
        "polygon: [[0, 0], [1, 0], [1, 1], [0, 1]]\n"
        "delta: 0.9\n"
        "seed: 2\n"
        "robots:\n"
        "  - {}\n"
        "  - {delta: 0.92, forbidden: [[0.4, 0.4], [0.6, 0.4], [0.6, 0.6], [0.4, 0.6]]}\n"
    )
    p = ost("run", "--file", str(f), "--json")
    assert p.returncode == 0, p.stderr
    out = json.loads(p.stdout)
    import numpy as np
    from shapely.geometry import Polygon, box

    s2 = Polygon(np.asarray(out["shares"][1]).reshape(-1, 2))
    assert s2.intersection(box(0.4, 0.4, 0.6, 0.6)).area <= 1e-9
    assert out["metrics"]["covered"] > 0.9
    p = ost("run", "--file", str(f))  # human output
    assert p.returncode == 0 and "robot 2" in p.stdout


@pytest.mark.slow
def test_reproduce_quick_writes_report(tmp_path):
    p = ost("reproduce", "--out", str(tmp_path), "--quick", "--runs", "1", "--no-progress", timeout=120)
    assert p.returncode == 0, p.stderr
    for name in (
        "report.md",
        "fig4.png",
        "fig4_trace.csv",
        "table2.csv",
        "table3.csv",
        "table4.csv",
        "nfz.csv",
        "nfz.png",
        "targets_rules.csv",
        "missions.csv",
        "table2_partitions.png",
    ):
        assert (tmp_path / name).stat().st_size > 0, name
    report = (tmp_path / "report.md").read_text()
    for heading in ("Fig. 4", "Table 2", "Table 3", "Table 4", "no-fly zone", "§5.1"):
        assert heading in report
