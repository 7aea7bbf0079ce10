"""Hypothesis strategies shared by the core's property tests: random small scenarios (bases
anywhere or at the sweep starts) and coordination policies of every trigger kind."""

from hypothesis import strategies as st

from ost_ros.coordination import CoordinationPolicy
from ost_ros.model import AgentSpec, Grid
from ost_ros.partition import choose_partition
from ost_ros.scenario import build_scenario, generate_objects


@st.composite
def scenarios(draw, width=(4, 24), height=(3, 12), agents=(1, 5), objects=(0, 7)):
    w, h = draw(st.integers(*width)), draw(st.integers(*height))
    n = draw(st.integers(*agents))
    m, k = choose_partition(n, Grid(w, h)) if n <= min(w, h) else (1, 1)
    n = m * k
    nmax = draw(st.integers(1, n))
    count = draw(st.integers(objects[0], min(objects[1], w * h)))
    objs = generate_objects(count, draw(st.integers(0, 10**6)), Grid(w, h), nmax)
    bases = None
    if draw(st.booleans()):  # bases anywhere, not only at the sweep starts
        bases = [AgentSpec(i, (draw(st.integers(0, w - 1)), draw(st.integers(0, h - 1)))) for i in range(n)]
    return build_scenario(Grid(w, h), objs, partition=(m, k), agents=bases, nmax=nmax)


policies = st.one_of(
    st.builds(CoordinationPolicy, ci=st.integers(1, 9)),
    st.builds(CoordinationPolicy, interval=st.integers(1, 40)),
    st.builds(CoordinationPolicy, area_fraction=st.sampled_from([0.1, 0.25, 0.5, 1.0])),
)
