"""Behaviour kept: every output of the corpus (``tests/corpus/runs.py``) is byte-identical to the
recorded one — results of every protocol, engine, organisation and failure mode, and both
papers' reproduction tables. A change that means to alter behaviour re-records the corpus
(``tests/corpus/record.py``) and says why in its commit."""

import json

import pytest

from tests.corpus.harness import EXPECTED, digest, prepare, run_command, run_reproduction
from tests.corpus.runs import REPRODUCTIONS, commands, generate_commands

RECORDED = json.loads(EXPECTED.read_text())
COMMANDS = dict(commands())


@pytest.fixture(scope="module")
def scratch(tmp_path_factory):
    d = tmp_path_factory.mktemp("corpus")
    prepare(d)
    for _, argv in generate_commands():  # every other command reads these scenarios
        assert run_command(argv, d)[0] == 0
    return d


def test_corpus_is_large_enough():
    sims = [n for n in COMMANDS if n.startswith("sim-")]
    assert len(sims) >= 60 and set(RECORDED) == set(COMMANDS) | {n for n, _ in REPRODUCTIONS}


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_output_is_unchanged(name, scratch):
    code, data = run_command(COMMANDS[name], scratch)
    want = RECORDED[name]
    assert (code, len(data), digest(data)) == (want["exit"], want["bytes"], want["sha256"]), (
        f"ost {' '.join(COMMANDS[name])}: output changed"
    )


@pytest.mark.slow
@pytest.mark.parametrize("name, argv", REPRODUCTIONS)
def test_reproduction_tables_are_unchanged(name, argv, tmp_path):
    assert run_reproduction(argv, tmp_path) == RECORDED[name]
