"""The study runner (ost_ros.study.runner): rows in spec order whatever order the runs finish
in, chunks that cover every spec once, a journal that resumes an interrupted study without
running a written row again (a torn last line is run again), and one that belongs to another
study is refused in one line."""

import json
import math
import subprocess
import sys
from dataclasses import dataclass

import numpy as np
import pytest

from ost_ros.errors import UsageError
from ost_ros.study.executors import ClusterSpec, Executor
from ost_ros.study.runner import Study, chunks, run_study
from ost_ros.study.stats import interval, t95

CALLS: list[int] = []


@dataclass(frozen=True)
class Row:
    spec: int
    square: int
    root: float


def square(spec: int) -> Row:
    CALLS.append(spec)
    return Row(spec, spec * spec, math.sqrt(spec))


def numpy_row(spec: int) -> dict:
    return {"n": np.int64(spec), "x": np.float64(spec) / 3, "ok": np.bool_(spec % 2)}


def study(n: int = 40) -> Study:
    return Study("squares", list(range(n)), square, weight=lambda s: 1 + s, row_type=Row)


class Backwards(Executor):
    """Everything finishes in the reverse order of submission."""

    def map_unordered(self, fn, items):
        return reversed([fn(x) for x in items])


class Interrupted(Exception):
    pass


def stop_at(count: int):
    """An ``on_rows`` that interrupts the study once ``count`` rows are in (a kill, in-process)."""

    def check(done: int) -> None:
        if done >= count:
            raise Interrupted

    return check


def test_chunks_cover_every_spec_once_and_shrink():
    todo = list(enumerate(range(1000)))
    parts = chunks(todo, [1.0] * 1000, workers=2)
    assert [x for p in parts for x in p] == todo
    sizes = [len(p) for p in parts]
    assert sizes[0] > sizes[-2] and len(parts) <= 64 * 2 + 1
    assert min(sizes[:-1]) >= 1000 // (64 * 2)


def test_rows_are_in_spec_order_whatever_finishes_first():
    ahead = run_study(study(), Backwards())
    assert [r.spec for r in ahead.rows] == list(range(40))
    assert ahead.rows == run_study(study(), Executor()).rows
    assert len(ahead.cpu) == 40 and ahead.timing.resumed == 0


def test_numpy_values_come_back_as_plain_numbers():
    rows = run_study(Study("np", [1, 2], numpy_row), Executor()).rows
    assert rows == [{"n": 1, "x": 1 / 3, "ok": True}, {"n": 2, "x": 2 / 3, "ok": False}]
    assert type(rows[0]["n"]) is int and type(rows[0]["ok"]) is bool


def test_an_interrupted_study_resumes_without_rerunning_its_rows(tmp_path):
    whole = run_study(study(), Executor()).rows
    CALLS.clear()
    with pytest.raises(Interrupted):
        run_study(study(), Executor(), tmp_path, on_rows=stop_at(10))
    first = list(CALLS)
    journal = tmp_path / "partial-squares.jsonl"
    lines = journal.read_text().splitlines()
    assert json.loads(lines[0])["study"] == "squares" and len(lines) == 1 + len(first)
    with journal.open("a") as fh:  # a kill tore the next line
        fh.write('{"i": 99, "cpu": 0.1, "row": {"spe')
    CALLS.clear()
    again = run_study(study(), Executor(), tmp_path)
    assert sorted(CALLS) == sorted(set(range(40)) - set(first))  # nothing written is run again
    assert again.timing.resumed == len(first) and again.rows == whole
    again.finish()
    assert not journal.exists()


def test_a_journal_of_another_study_is_refused(tmp_path):
    with pytest.raises(Interrupted):
        run_study(study(), Executor(), tmp_path, on_rows=stop_at(1))
    with pytest.raises(UsageError, match="other options"):
        run_study(study(41), Executor(), tmp_path)


def test_t_intervals_come_from_scipy():
    assert t95(16) == pytest.approx(2.120, abs=5e-4)  # the hand-copied table said 2.093
    assert t95(9) == pytest.approx(2.262, abs=5e-4) and math.isnan(t95(0))
    mean, half = interval([1.0, 2.0, 3.0, 4.0])
    assert mean == 2.5 and half == pytest.approx(t95(3) * np.std([1, 2, 3, 4], ddof=1) / 2)


@pytest.mark.parametrize(
    "text, kind",
    [
        ("tcp://10.0.0.5:8786", "address"),
        ("tls://h:8786", "address"),
        ("s.json", "file"),
        ("local:3", "local"),
    ],
)
def test_cluster_flags(text, kind):
    assert ClusterSpec.parse(text).kind == kind


@pytest.mark.parametrize("text", ["local:0", "local:x", "tcp://nohost", "udp://h:1", "scheduler.yaml"])
def test_bad_cluster_flags_are_one_line(text, capsys, tmp_path):
    from ost_ros.cli import main

    with pytest.raises(SystemExit) as e:
        main(["reproduce", "--quick", "--out", str(tmp_path), "--cluster", text])
    err = capsys.readouterr().err
    assert e.value.code == 2 and err.count("\n") == 1 and "--cluster" in err


def test_jobs_and_cluster_together_are_one_line(capsys, tmp_path):
    from ost_ros.cli import main

    assert main(["compare", "--quick", "--out", str(tmp_path), "--jobs", "2", "--cluster", "local:2"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "one or the other" in err


def test_an_unreachable_scheduler_is_one_line(capsys, tmp_path):
    from ost_ros.cli import main

    assert main(["faults", "report", "--quick", "--cluster", str(tmp_path / "none.json")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no such scheduler file" in err


def test_dask_is_imported_only_for_a_cluster():
    code = (
        "import sys\n"
        "from ost_ros.cli import build_parser\n"
        "args = build_parser().parse_args(['reproduce', '--out', 'x', '--jobs', '2'])\n"
        "from ost_ros.study import compare, reproduce, report\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] in ('dask', 'distributed')))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
