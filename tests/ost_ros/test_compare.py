"""``ost compare`` (ost_ros.study.compare): every registered protocol, and CCP with each planner,
runs on the same object sets; the summary's intervals and the report's statements are computed
from the rows (checked against a recomputation), and the files a user opens are written."""

import math
import statistics

from ost_ros import protocols
from ost_ros.study.compare import PAPER, findings, run_all, summarise, variants, write_all
from ost_ros.study.design import Design, Task
from ost_ros.study.executors import Executor
from ost_ros.study.stats import t95


def tasks():
    d = Design()
    return [Task(10, 10, s, d.object_seed(10, s), ()) for s in range(2)]


def test_every_protocol_and_planner_is_compared():
    # every protocol of the registry: those with triggers at CI=1 and CI=M; CCP also improved
    want = {"CCP CI=1 improved", "CCP CI=M improved"}
    for spec in protocols.REGISTRY.values():
        name = spec.name.upper()
        want |= {f"{name} CI=1", f"{name} CI=M"} if spec.capabilities.triggers else {name}
    assert {v.label for v in variants()} == want
    assert {"HCP", "AUCTION", "CCP CI=1", "NCP CI=M"} <= want
    assert {v.protocol for v in variants()} == set(protocols.names())


def test_compare_writes_a_report_computed_from_its_runs(tmp_path):
    rows, outcome = run_all(tasks(), Executor(), progress=False)
    assert len(rows) == 2 * len(variants()) and outcome.timing.wall > 0
    cells = summarise(rows)
    for c in cells:
        xs = [r.makespan for r in rows if r.variant == c.variant]
        assert math.isclose(c.makespan, statistics.mean(xs))
        assert math.isclose(c.half, t95(1) * statistics.stdev(xs) / math.sqrt(2))
    text = "\n".join(findings(rows, cells))
    # the improved planner is never worse than the paper's on these runs, and the report says so
    paper = {r.set: r.makespan for r in rows if r.variant == PAPER}
    better = {r.set: r.makespan for r in rows if r.variant == "CCP CI=1 improved"}
    assert all(better[s] <= paper[s] for s in paper)
    assert "Improved planner vs the paper's at CI=1" in text and "never worse: yes" in text
    files = write_all(rows, outcome.timing, tmp_path)
    assert files[:3] == ["report.md", "runs.csv", "summary.csv"] and files[3] == "compare_N10.png"
    report = (tmp_path / "report.md").read_text()
    assert "| 10 | 10 |" in report and "![compare_N10.png](compare_N10.png)" in report
    assert len((tmp_path / "runs.csv").read_text().splitlines()) == 1 + len(rows)


def test_compare_with_latency_adds_every_protocol_that_runs_without_a_barrier(tmp_path):
    """``ost compare --latency L:J``: each variant that runs without a barrier (every one) also
    runs so; the findings give each one's cost against itself in lockstep."""
    from ost_ros.realtime.run import REALTIME

    rows, outcome = run_all(tasks()[:1], Executor(), progress=False, latency=(3.0, 2.0))
    labels = {r.variant for r in rows}
    realtime = {v for v in labels if v.endswith(" L=3:2")}
    assert {v.split(" L=")[0] for v in realtime} == {v.label for v in variants() if v.protocol in REALTIME}
    assert any(v.startswith("HCP L=") for v in labels)
    text = "\n".join(findings(rows, summarise(rows)))
    assert "CCP CI=1 improved L=3:2 (no barrier) vs CCP CI=1 improved in lockstep" in text
    write_all(rows, outcome.timing, tmp_path)
    assert "`ost sim --latency 3:2`" in (tmp_path / "report.md").read_text()
