"""The reproduction study and the study verbs: a tiny design end to end (files, tables, claims,
reproducible from its seed), the speedup formula, and one-line errors for bad input."""

import csv
import math
import subprocess
import sys
from dataclasses import replace

import pytest

from ost_ros.cli import main
from ost_ros.study.design import Design, compared, scenario_of
from ost_ros.study.executors import Executor, ProcessPool
from ost_ros.study.report import means, speedup, write_all
from ost_ros.study.reproduce import run_design
from ost_ros.study.stats import interval

TINY = Design(agents=(10, 20), objects=(1, 10), sets=1, cis=(1, 10), compare_agents=(10,), seed=3)


def test_design_matches_the_paper():
    d = Design()
    tasks = d.tasks()
    assert len(tasks) == 5 * 8 * 10
    full = [t for t in tasks if t.agents in (10, 50)]
    # CCP CI=1, CI=M and the 7 other CIs, and every other protocol of the registry as compared
    # (HCP, the auction, ..., NCP at CI=1 and CI=M)
    assert all(
        set(compared()) <= set(t.variants) and len(t.variants) == len(compared()) + len(d.cis) - 1
        for t in full
    )
    # The same object set for every N.
    a = scenario_of(next(t for t in tasks if (t.agents, t.objects, t.set) == (10, 20, 3)))
    b = scenario_of(next(t for t in tasks if (t.agents, t.objects, t.set) == (50, 20, 3)))
    assert a.objects == b.objects and a.partition == (5, 2) and b.partition == (10, 5)


def test_speedup_formula():
    c = {(10, 5, "v"): 1000.0, (20, 5, "v"): 400.0}
    assert speedup(c, "v", 5, 20) == pytest.approx(1.25)  # (1000/400)·(10/20)
    assert speedup(c, "v", 5, 30) is None


def test_tiny_study_end_to_end(tmp_path):
    with ProcessPool(2) as pool:
        rows, outcome = run_design(TINY, pool, progress=False)
    rows1, _ = run_design(TINY, Executor(), progress=False)
    assert rows == rows1  # reproducible, whatever the workers
    timing = outcome.timing
    # N=10: every protocol of the registry as compared (CCP and NCP at CI=1 and M, HCP, ...) and
    # CCP CI=10; N=20: CCP CI=1, M — for each of the 2 M
    assert len(rows) == 2 * (len(compared()) + len(TINY.cis) - 1) + 2 * 2
    assert all(r.makespan >= r.lower_bound > 0 for r in rows)
    assert timing.workers == 2 and timing.cpu > 0 and timing.wall > 0
    report = write_all(tmp_path, TINY, rows, timing, quick=True)
    text = report.read_text()
    for name in ("runs.csv", "summary.csv", "table1.csv", "table3.csv", "fig7.png", "fig9.png", "fig11.png"):
        assert (tmp_path / name).stat().st_size > 0
    assert "## The paper's claims" in text and "| 10 | 1.00 / 1.00 (+0.00) |" in text
    with (tmp_path / "runs.csv").open() as f:
        assert len(list(csv.DictReader(f))) == len(rows)
    c = means(rows)
    assert c[(10, 10, "HCP")] > c[(10, 10, "CCP CI=M")]


def test_readings_spread_and_the_one_object_row(tmp_path):
    design = replace(TINY, table3_seeds=(3, 4))
    rows, outcome = run_design(design, Executor(), progress=False)
    timing = outcome.timing
    assert {r.study_seed for r in rows} == {3, 4}
    assert len([r for r in rows if r.study_seed == 4]) == 2 * 2 * 2  # CI=1, CI=M at N=10, 20
    write_all(tmp_path, design, rows, timing, quick=True)
    text = (tmp_path / "report.md").read_text()
    read = list(csv.DictReader((tmp_path / "readings.csv").open()))
    assert [(r["time"], r["table3_ci"]) for r in read] == [
        ("return to base", "1"), ("return to base", "M"), ("last delivery", "1"), ("last delivery", "M"),
    ]  # fmt: skip
    assert [r["documented"] for r in read] == ["True", "False", "False", "False"]
    assert "## Readings: how much rides on them" in text and "(documented)" in text
    # claim 3 is judged per CI, by the paper's standard (every M > 30 cell): none in this design
    assert "CI=1: no M > 30 cells in this design" in text and "CI=M: no M > 30 cells" in text
    # Table 3 cells carry their range over the two seeds, and the mean lies in it
    t3 = [r for r in csv.DictReader((tmp_path / "table3.csv").open()) if r["time"] == "return to base"]
    for r in t3:
        assert float(r["N=20 low"]) <= float(r["N=20"]) <= float(r["N=20 high"])
    assert "[" in text.split("### CCP CI=1")[1].split("###")[0]
    for r in csv.DictReader((tmp_path / "summary.csv").open()):  # one object set: no interval
        assert r["sets"] == "1" and r["ci95_low"] == r["ci95_high"] == "nan"
    # M = 1 taken apart: the parts are in time order, and each N's makespan is the run's
    m1 = list(csv.DictReader((tmp_path / "one_object.csv").open()))
    c = means(rows, "makespan", 3)
    for r in m1:
        parts = [float(r[k]) for k in ("search_end", "first_carry", "last_delivery", "makespan")]
        assert parts == sorted(parts) and parts[-1] == pytest.approx(c[(int(r["N"]), 1, "CCP CI=1")])
    assert "## The M = 1 row taken apart" in text
    for name in ("fig7.png", "ours_n10.png", "fig9.png", "fig11.png"):
        assert (tmp_path / name).stat().st_size > 0


def test_interval_is_students_t():
    mean, half = interval([10.0, 12.0, 14.0])
    assert mean == 12.0 and half == pytest.approx(4.303 * 2 / 3**0.5, rel=1e-3)  # t(0.975, 2) = 4.303
    mean, half = interval([5.0])  # one sample has no interval
    assert mean == 5.0 and math.isnan(half)


@pytest.mark.parametrize("seeds", ["x", "5-2", "1-30", "-1"])
def test_bad_seeds_are_one_line(tmp_path, capsys, seeds):
    with pytest.raises(SystemExit) as e:
        main(["reproduce", "--out", str(tmp_path), "--seeds", seeds])
    assert e.value.code == 2 and "--seeds" in capsys.readouterr().err


def test_cli_errors_are_one_line(tmp_path, capsys):
    f = tmp_path / "file"
    f.write_text("x")
    assert main(["reproduce", "--out", str(f)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "not a directory" in err
    big = tmp_path / "big.yaml"
    assert (
        main(
            [
                "generate",
                "--agents",
                "3",
                "--objects",
                "11",
                "--seed",
                "1",
                "--width",
                "30",
                "--height",
                "9",
                "--nmax",
                "3",
                "-o",
                str(big),
            ]
        )
        == 0
    )
    assert main(["optimal", str(big)]) == 2
    assert "too many for the exact search" in capsys.readouterr().err


def test_optimal_verb(tmp_path):
    s = tmp_path / "s.yaml"
    assert (
        main(
            [
                "generate",
                "--agents",
                "3",
                "--objects",
                "4",
                "--seed",
                "2",
                "--width",
                "30",
                "--height",
                "9",
                "--nmax",
                "3",
                "-o",
                str(s),
            ]
        )
        == 0
    )
    r = subprocess.run(
        [sys.executable, "-m", "ost_ros", "optimal", str(s), "--json"],
        capture_output=True,
        text=True,
        check=True,
    )
    import json

    out = json.loads(r.stdout)
    assert out["proven"] and out["lower_bound"] <= out["optimal"] <= out["ccp"]
    assert out["ccp_gap"] == pytest.approx((out["ccp"] - out["optimal"]) / out["optimal"], abs=1e-4)


def test_sim_reports_bound_and_engines_agree(tmp_path):
    s = tmp_path / "s.yaml"
    assert (
        main(
            [
                "generate",
                "--agents",
                "4",
                "--objects",
                "6",
                "--seed",
                "5",
                "--width",
                "40",
                "--height",
                "12",
                "--nmax",
                "4",
                "-o",
                str(s),
            ]
        )
        == 0
    )
    outs = []
    for proto in ("ccp", "hcp"):
        for engine in ("step", "event"):
            r = subprocess.run(
                [
                    sys.executable,
                    "-m",
                    "ost_ros",
                    "sim",
                    str(s),
                    "--protocol",
                    proto,
                    "--engine",
                    engine,
                    "--json",
                ],
                capture_output=True,
                text=True,
                check=True,
            )
            outs.append(r.stdout)
    import json

    a, b, c, d = (json.loads(x) for x in outs)
    assert a == b and c == d and a["lower_bound"] <= min(a["makespan"], c["makespan"])
