"""Running the corpus: each command in-process through ``ost``'s own ``main``, output hashed."""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import re
from pathlib import Path

from ost_ros.cli import main
from tests.corpus.runs import REPRODUCTIONS, STATE, commands

EXPECTED = Path(__file__).with_name("expected.json")
# Lines of a generated report that state how long the run took on this machine.
_TIMING = re.compile(r"wall time|CPU s|load average|\"elapsed_s\"", re.IGNORECASE)


def untimed(data: bytes) -> bytes:
    """The output without the lines that say how long it took (they differ from run to run)."""
    return b"\n".join(line for line in data.split(b"\n") if not _TIMING.search(line.decode()))


def prepare(scratch: Path) -> None:
    (scratch / "state.json").write_text(json.dumps(STATE))


def run_command(argv: list[str], scratch: Path) -> tuple[int, bytes]:
    """Exit code and every byte the command wrote (stdout, then any file it wrote with -o)."""
    argv = [a.replace("{dir}", str(scratch)) for a in argv]
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main(argv)
    data = buf.getvalue().encode()
    if "-o" in argv:
        data += Path(argv[argv.index("-o") + 1]).read_bytes()
    return code, untimed(data)


def run_reproduction(argv: list[str], out: Path) -> dict[str, str]:
    """Digest of every CSV and of the report (timing lines left out) the command writes."""
    argv = [a.replace("{out}", str(out)) for a in argv]
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        code = main(argv)
    assert code == 0, f"ost {' '.join(argv)} exited with {code}"
    return digests_of(out)


def digests_of(out: Path) -> dict[str, str]:
    """Digest of every CSV and of the report (timing lines left out) in a study's directory."""
    digests = {}
    for f in sorted(out.iterdir()):
        if f.suffix == ".csv":
            digests[f.name] = digest(f.read_bytes())
        elif f.suffix == ".md":
            digests[f.name] = digest(untimed(f.read_bytes()))
    return digests


def digest(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def record(scratch: Path) -> dict:
    prepare(scratch)
    runs = {}
    for name, argv in commands():
        code, data = run_command(argv, scratch)
        runs[name] = {"exit": code, "sha256": digest(data), "bytes": len(data)}
    for name, argv in REPRODUCTIONS:
        runs[name] = run_reproduction(argv, scratch / name)
    return runs
