"""Print a result file (the JSON of ``ost sim --json``) as ``ost sim`` prints it.

python -m world_node.report RESULT.json [--json]
"""

from __future__ import annotations

import json
import sys

from ost_ros.result import RunResult


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if not argv:
        print("usage: python -m world_node.report RESULT.json [--json]", file=sys.stderr)
        return 2
    try:
        with open(argv[0]) as f:
            text = f.read()
        data = json.loads(text)
        if "--json" in argv[1:]:
            print(json.dumps(data, indent=1))
        else:
            print(RunResult.from_dict(data).summary())
    except (OSError, ValueError, KeyError, TypeError) as exc:
        print(f"report: error: {argv[0]}: cannot read the result ({exc.__class__.__name__})", file=sys.stderr)
        return 2
    return 0 if data.get("completed") else 1


if __name__ == "__main__":
    sys.exit(main())
