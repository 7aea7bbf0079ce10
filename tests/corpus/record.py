"""Record the corpus's outputs into ``expected.json`` (only when behaviour is meant to change).

.venv/bin/python tests/corpus/record.py
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: tests.corpus
from tests.corpus.harness import EXPECTED, record

if __name__ == "__main__":
    with tempfile.TemporaryDirectory() as tmp:
        runs = record(Path(tmp))
    EXPECTED.write_text(json.dumps(runs, indent=1, sort_keys=True) + "\n")
    print(f"{len(runs)} corpus entries written to {EXPECTED}")
