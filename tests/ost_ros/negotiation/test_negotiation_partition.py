"""``ost negotiate partition``: negotiated search subareas for robots of different speeds.

(Named test_negotiation_partition.py, not test_partition.py: tests/ost_ros/test_partition.py
exists, and pytest's default import mode cannot hold two test modules of the same basename.)
"""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import shapely
from hypothesis import given, settings
from hypothesis import strategies as st

from ost_ros.cli import main
from ost_ros.model import Subarea, arrival
from ost_ros.negotiation import multiparty
from ost_ros.negotiation.agents import AreaNegotiator
from ost_ros.negotiation.errors import NegotiationError
from ost_ros.negotiation.partition import (
    SearchReward,
    SearchRobot,
    SearchTeam,
    apply_flags,
    forbidden_polygon,
    negotiate_partition,
    patience_discounts,
    region_sweep,
    resolve,
    search_time,
    sweep_length,
    sweep_path,
)
from ost_ros.negotiation.proposals import AreaSearch
from ost_ros.search import plan_length, sweep_waypoints

REPO = Path(__file__).resolve().parents[3]
FAST = AreaSearch(population=8, generations=2)


def team(width, height, periods, zones=None, seed=0, **kw):
    zones = zones or {}
    return SearchTeam(
        width,
        height,
        tuple(SearchRobot(i, p, tuple(zones.get(i, ()))) for i, p in enumerate(periods)),
        seed=seed,
        **kw,
    )


def sensed(path, height, width):
    """Cells within Chebyshev distance 1 of a visited cell (the 3×3 sensor)."""
    seen = np.zeros((height + 2, width + 2), dtype=bool)
    for x, y in path:
        seen[y : y + 3, x : x + 3] = True  # padded by one on every side
    return seen[1:-1, 1:-1]


def check_sweep(mask):
    pts = region_sweep(mask)
    path = sweep_path(pts)
    h, w = mask.shape
    assert all(0 <= x < w and 0 <= y < h for x, y in path), "the sweep leaves the grid"
    assert all(abs(a[0] - b[0]) + abs(a[1] - b[1]) == 1 for a, b in zip(path, path[1:])), "not unit moves"
    assert len(path) - 1 == sweep_length(pts)
    missed = mask & ~sensed(path, h, w)
    assert not missed.any(), f"cells never sensed: {np.argwhere(missed)[:5].tolist()}"


def check_partition(res):
    t = res.team
    owner = res.owner
    assert owner.shape == (t.height, t.width)
    assert owner.min() >= 0 and owner.max() < len(t.robots), "every cell has exactly one owner"
    assert [r.cells for r in res.robots] == np.bincount(owner.ravel(), minlength=len(t.robots)).tolist()
    assert sum(r.cells for r in res.robots) == t.width * t.height
    allowed = t.allowed()
    for i in range(len(t.robots)):
        assert not ((owner == i) & ~allowed[i]).any(), f"robot {i} was given a forbidden cell"
        check_sweep(owner == i)
        moves = sweep_length(region_sweep(owner == i))
        assert res.robots[i].moves == moves
        assert res.robots[i].search_time == arrival(0, moves, t.robots[i].period)
    assert res.team_time == max(r.search_time for r in res.robots)


# ------------------------------------------------------------------ the sweep -------------------
@settings(max_examples=150)
@given(st.integers(1, 12), st.integers(1, 12), st.data())
def test_sweep_senses_every_cell_of_any_region(h, w, data):
    cells = data.draw(st.lists(st.booleans(), min_size=h * w, max_size=h * w))
    mask = np.array(cells, dtype=bool).reshape(h, w)
    if mask.any():
        check_sweep(mask)
    else:
        assert region_sweep(mask) == []


@settings(max_examples=100)
@given(st.integers(0, 6), st.integers(0, 6), st.integers(1, 14), st.integers(1, 14))
def test_sweep_of_a_rectangle_is_the_osts(x0, y0, w, h):
    mask = np.zeros((y0 + h + 2, x0 + w + 2), dtype=bool)
    mask[y0 : y0 + h, x0 : x0 + w] = True
    area = Subarea(x0, y0, w, h)
    assert region_sweep(mask) == sweep_waypoints(area)
    assert sweep_length(region_sweep(mask)) == plan_length(sweep_waypoints(area))


def test_sweep_picks_the_cheapest_band_offset():
    # a 2-cell stub on row 1 above a 3-row strip (rows 2-4): bands from row 1 need two full
    # passes (19 + 2 + 19 = 40 moves); bands from row -1 sense the stub with a one-cell pass on
    # row 1 and the strip with one pass on row 3 (1 + 2 + 19 = 22, first pass right to left)
    mask = np.zeros((8, 20), dtype=bool)
    mask[1, 0:2] = True
    mask[2:5, :] = True
    pts = region_sweep(mask)
    assert pts == [(1, 1), (0, 1), (0, 3), (19, 3)]
    assert sweep_length(pts) == 22
    check_sweep(mask)


# ------------------------------------------------------------------ resolution ------------------
rects = st.tuples(st.integers(0, 7), st.integers(0, 5), st.integers(0, 7), st.integers(0, 5))


@settings(max_examples=150)
@given(st.integers(1, 4), st.data())
def test_resolve_covers_every_cell_once_with_an_allowed_robot(r_n, data):
    h, w = 6, 8
    claims = np.zeros((r_n, h, w), dtype=bool)
    for i in range(r_n):
        if data.draw(st.booleans()):
            x0, y0, x1, y1 = data.draw(rects)
            claims[i, min(y0, y1) : max(y0, y1) + 1, min(x0, x1) : max(x0, x1) + 1] = True
    allowed = np.array(
        data.draw(st.lists(st.booleans(), min_size=r_n * h * w, max_size=r_n * h * w)), dtype=bool
    ).reshape(r_n, h, w)
    allowed[0] |= ~allowed.any(axis=0)  # no cell forbidden to everyone
    periods = data.draw(st.lists(st.integers(1, 4), min_size=r_n, max_size=r_n))
    res = resolve(claims, allowed, periods)
    owner = res.owner
    assert owner.min() >= 0 and owner.max() < r_n
    assert allowed[owner, np.arange(h)[:, None], np.arange(w)[None, :]].all()
    # a rectangle claim is one piece: its cells that nobody else claims and it may take stay its own
    only = claims.sum(axis=0) == 1
    for i in range(r_n):
        keep = claims[i] & only & allowed[i]
        assert (owner[keep] == i).all()
    assert res.fragments == 0


def test_resolve_releases_cut_off_pieces_and_prefers_the_faster_neighbour():
    claims = np.zeros((2, 3, 6), dtype=bool)
    claims[0, :, :3] = True
    claims[0, 0, 5] = True  # a cut-off piece of robot 0's claim
    claims[1, :, 3:] = True
    claims[1, 0, 5] = False
    allowed = np.ones_like(claims)
    res = resolve(claims, allowed, [1, 1])
    assert res.fragments == 1 and res.unclaimed == 1
    assert res.owner[0, 5] == 1  # its only neighbours are robot 1's
    # a gap between a slow and a fast robot goes to the one with the least load (period × cells)
    claims = np.zeros((2, 1, 5), dtype=bool)
    claims[0, 0, :2] = True
    claims[1, 0, 3:] = True
    res = resolve(claims, np.ones_like(claims), [3, 1])
    assert res.owner[0, 2] == 1


def test_cell_forbidden_to_every_robot_is_an_error():
    claims = np.ones((2, 2, 2), dtype=bool)
    allowed = np.ones_like(claims)
    allowed[:, 1, 0] = False
    with pytest.raises(NegotiationError, match=r"cell \(0, 1\) is forbidden to every robot"):
        resolve(claims, allowed, [1, 1])
    t = team(10, 4, [1, 2], {0: [(0, 0, 3, 3)], 1: [(2, 1, 5, 2)]})
    with pytest.raises(NegotiationError, match=r"cell \(2, 1\) is forbidden to every robot"):
        negotiate_partition(t)


# ------------------------------------------------------------------ set-up ----------------------
def test_search_time_is_the_osts_clock():
    assert [search_time(m, 1) for m in (0, 1, 10)] == [0, 1, 10]
    assert [search_time(m, 3) for m in (0, 1, 10)] == [0, 1, 28]  # moves in steps 0, 3, ..., 27


def test_patience_discounts_reach_the_targets_together():
    shares = np.array([3, 3, 1, 1]) / 8
    d = patience_discounts(shares, 0.95)
    assert d[0] == pytest.approx(0.95) and d[1] == pytest.approx(0.95)
    k = np.log(shares.max()) / np.log(0.95)
    assert d**k == pytest.approx(shares)  # every claim is at its target in round K
    assert (patience_discounts(np.full(5, 0.2), 0.9) == 0.9).all()
    assert patience_discounts(np.array([1.0]), 0.9).tolist() == [0.9]


def test_reward_prices_sweep_waste():
    c = 1 / 60
    r = SearchReward(cell=c)
    strip = shapely.box(0, 0, 60 * c, 3 * c)  # one pass, no waste but the walk's end cells
    tall = shapely.box(0, 0, 45 * c, 4 * c)  # same area, 4 rows: two passes
    assert r.swept(np.array([strip.bounds]))[0] == pytest.approx(3 * c * 60 * c)
    assert r.swept(np.array([tall.bounds]))[0] > r.swept(np.array([strip.bounds]))[0]
    from ost_ros.negotiation.tasks import AreaTask

    task = AreaTask(shapely.box(0, 0, 1, 0.4))
    vals = r.batch_values(task, np.array([strip, tall]), [])
    assert vals[0] > vals[1]
    assert r.value(task, strip, []) == pytest.approx(vals[0])


# ------------------------------------------------------------------ the whole job ---------------
ZONES = {0: [(0, 0, 5, 3)], 2: [(20, 6, 29, 11), (10, 0, 12, 2)]}


@pytest.fixture(scope="module")
def recorded():
    """One negotiated partition, recording what each negotiator was built with."""
    seen = []

    class Recording(AreaNegotiator):
        def __post_init__(self):
            super().__post_init__()
            seen.append((self.agent_id, self.reward))

    mp = pytest.MonkeyPatch()
    mp.setattr(multiparty, "AreaNegotiator", Recording)
    try:
        res = negotiate_partition(team(30, 12, [1, 2, 2], ZONES, seed=3), search=FAST)
    finally:
        mp.undo()
    return res, seen


def test_partition_covers_once_and_respects_forbidden_zones(recorded):
    res, _ = recorded
    check_partition(res)
    assert res.negotiation.status == "agreed"


def test_forbidden_zones_reach_only_their_own_negotiator(recorded):
    res, seen = recorded
    assert [i for i, _ in seen] == [0, 1, 2]
    scale = res.team.scale
    own = {i: forbidden_polygon(ZONES.get(i, []), scale) for i in range(3)}
    for i, reward in seen:
        if own[i] is None:
            assert reward.forbidden is None
        else:
            assert reward.forbidden.equals(own[i])
        for j in range(3):
            if j != i and own[j] is not None and reward.forbidden is not None:
                assert reward.forbidden.intersection(own[j]).area == 0, f"robot {j}'s zone reached robot {i}"
    # and nothing of a zone travels in a message: offers carry claims only, never on own forbidden ground
    for msg in res.negotiation.log:
        claim = res.setup.task.decode(msg.params)
        zone = own[msg.sender]
        if zone is not None and not claim.is_empty:
            assert claim.intersection(zone).area < 1e-12


def test_equal_partition_violations_are_counted_not_fixed():
    t = team(30, 12, [1, 1], {0: [(0, 0, 4, 3)], 1: [(0, 8, 4, 11)]})
    res = negotiate_partition(t, search=FAST)
    check_partition(res)
    assert res.equal_partition == (2, 1)
    assert [r.equal_violations for r in res.robots] == [20, 0]  # robot 0 has the left half
    assert (res.equal_owner[0:4, 0:5] == 0).all()


@settings(max_examples=6)
@given(st.lists(st.integers(1, 3), min_size=2, max_size=3), st.data(), st.integers(0, 50))
def test_random_small_teams(periods, data, seed):
    zones = {}
    for i in range(len(periods)):
        if data.draw(st.booleans()):
            x0, y0 = data.draw(st.integers(0, 12)), data.draw(st.integers(0, 5))
            zones[i] = [(x0, y0, x0 + data.draw(st.integers(0, 3)), y0 + data.draw(st.integers(0, 2)))]
    t = team(16, 8, periods, zones, seed=seed)
    if not t.allowed().any(axis=0).all():
        with pytest.raises(NegotiationError, match="forbidden to every robot"):
            negotiate_partition(t, search=FAST)
        return
    check_partition(negotiate_partition(t, search=FAST))


def test_deterministic_by_seed():
    t = team(30, 12, [1, 2, 3], {1: [(10, 4, 14, 7)]}, seed=5)
    a, b = negotiate_partition(t, search=FAST), negotiate_partition(t, search=FAST)
    assert np.array_equal(a.owner, b.owner)
    da, db = a.to_dict(), b.to_dict()
    da.pop("elapsed_s"), db.pop("elapsed_s")
    assert da == db
    assert [m.to_dict() for m in a.negotiation.log] == [m.to_dict() for m in b.negotiation.log]


def test_heterogeneous_team_searches_faster_than_the_equal_partition():
    res = negotiate_partition(team(60, 24, [1, 1, 3, 3]))  # the command's own settings
    check_partition(res)
    assert res.equal_team_time == arrival(
        0, plan_length(sweep_waypoints(Subarea(0, 0, 15, 24))), 3
    )  # 4×1 strips
    assert res.team_time < res.equal_team_time
    fast, slow = [r.cells for r in res.robots[:2]], [r.cells for r in res.robots[2:]]
    assert min(fast) > max(slow)


def test_reward_rule_gives_a_valid_partition():
    res = negotiate_partition(team(30, 12, [1, 3], rule="reward"), search=FAST)
    check_partition(res)
    assert res.robots[0].cells > res.robots[1].cells


# ------------------------------------------------------------------ input -----------------------
def test_apply_flags():
    spec = {"grid": {"width": 50}, "robots": [{"id": 7, "period": 1}, {"id": 9}]}
    out = apply_flags(spec, height=20, periods="2,3", seed=4)
    assert out["grid"] == {"width": 50, "height": 20}
    assert out["robots"] == [{"id": 7, "period": 2}, {"id": 9, "period": 3}] and out["seed"] == 4
    assert spec["robots"][0]["period"] == 1  # the file's dict is not changed
    assert apply_flags({}, periods="1,2")["robots"] == [{"period": 1}, {"period": 2}]
    assert apply_flags({}, robots=3)["robots"] == 3
    assert apply_flags({})["robots"] == 4
    t = SearchTeam.from_spec(apply_flags({}, periods="1,2", width=30, height=12))
    assert (t.width, t.height, [r.period for r in t.robots], [r.id for r in t.robots]) == (
        30,
        12,
        [1, 2],
        [0, 1],
    )


def run_cli(capsys, *args):
    code = main(["negotiate", "partition", *args])
    out = capsys.readouterr()
    return code, out.out, out.err


BAD = [
    (["--periods", "1,0"], "robots[1].period: must be at least 1"),
    (["--periods", "1,x"], "--periods must be integers"),
    (["--robots", "2", "--periods", "1,2,3"], "3 periods for 2 robots"),
    (["--robots", "0"], "robots: must be at least 1"),
    (["--width", "0"], "grid.width: must be at least 1"),
    (["--delta", "1.5"], "delta must be in (0, 1)"),
    (["--rule", "fair"], "unknown rule"),
    (["--max-rounds", "0"], "max_rounds: must be at least 1"),
    (["--seed", "-1"], "seed: must be at least 0"),
    (["--width", "3", "--height", "1", "--robots", "4"], "more robots than cells"),
    (["--file", "/nonexistent/team.yaml"], "cannot read task file"),
    (["--plot", "/nonexistent/dir/x.png"], "does not exist"),
]
BAD_FILES = [
    ("grid: {width: 30, height: 12}\ncolour: blue\n", "unknown key 'colour'"),
    ("grid: {width: 30, depth: 12}\n", "grid: unknown key 'depth'"),
    ("grid: [30, 12]\n", "grid: expected a mapping"),
    ("robots: [{id: 0, speed: 2}]\n", "robots[0]: unknown key 'speed'"),
    ("robots: [{id: 0, period: fast}]\n", "robots[0].period: expected an integer"),
    ("robots: [{id: 0, period: 1.5}]\n", "robots[0].period: expected an integer"),
    ("robots: [{id: 0}, {id: 0}]\n", "robot ids must be unique"),
    ("robots: []\n", "need at least one robot"),
    ("grid: {width: 30, height: 12}\nrobots: [{forbidden: [[0, 0, 30, 3]]}, {}]\n", "forbidden[0]"),
    ("grid: {width: 30, height: 12}\nrobots: [{forbidden: [[5, 0, 2, 3]]}, {}]\n", "0 ≤ x0 ≤ x1"),
    ("robots: [{forbidden: [[0, 0, 3]]}, {}]\n", "expected [x0, y0, x1, y1]"),
    ("robots: [{forbidden: [0, 0, 3, 3]}, {}]\n", "expected [x0, y0, x1, y1]"),
    ("grid: {width: 10, height: 4}\nrobots: [{forbidden: [[0, 0, 9, 3]]}]\n", "forbidden to every robot"),
    ("delta: high\n", "delta: expected a number"),
    ("robots: [{period: 1}\n", "not valid YAML"),
    ("- 1\n", "must hold a mapping"),
]


@pytest.mark.parametrize("args, msg", BAD)
def test_bad_flags_are_one_line_exit_2(capsys, args, msg):
    code, out, err = run_cli(capsys, *args)
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and msg in err, err
    assert err.startswith("ost negotiate partition: error:")


@pytest.mark.parametrize("text, msg", BAD_FILES)
def test_bad_team_files_are_one_line_exit_2(capsys, tmp_path, text, msg):
    f = tmp_path / "team.yaml"
    f.write_text(text)
    code, out, err = run_cli(capsys, "--file", str(f))
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and msg in err, err


def test_file_and_flags(capsys, tmp_path):
    f = tmp_path / "team.yaml"
    f.write_text(
        "grid: {width: 24, height: 9}\nseed: 2\nrobots:\n"
        "  - {id: 4, period: 1, forbidden: [[0, 0, 3, 2]]}\n  - {id: 8, period: 2}\n"
    )
    code, out, _ = run_cli(capsys, "--file", str(f), "--periods", "1,3", "--json")
    assert code == 0
    d = json.loads(out)
    assert d["grid"] == {"width": 24, "height": 9} and d["seed"] == 2
    assert [(r["id"], r["period"]) for r in d["robots"]] == [(4, 1), (8, 3)]
    assert sum(r["cells"] for r in d["robots"]) == 24 * 9
    assert d["team_search_time"]["negotiated"] == max(r["search_time"] for r in d["robots"])
    code, out, _ = run_cli(capsys, "--file", str(f), "--robots", "3")
    assert code == 2


def test_command_line_end_to_end(tmp_path):
    png = tmp_path / "map.png"
    p = subprocess.run(
        [
            sys.executable,
            "-m",
            "ost_ros.cli",
            "negotiate",
            "partition",
            "--width",
            "30",
            "--height",
            "12",
            "--periods",
            "1,2",
            "--seed",
            "1",
            "--plot",
            str(png),
        ],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert p.returncode == 0, p.stderr
    assert "team search time: negotiated" in p.stdout and "equal (2x1)" in p.stdout
    assert png.stat().st_size > 10_000 and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    p = subprocess.run(
        [sys.executable, "-m", "ost_ros.cli", "negotiate", "partition", "--periods", "1,-2"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1 and "Traceback" not in p.stderr
