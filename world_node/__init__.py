"""ROS 2 node package of the OST system (docs/architecture.md has the map)."""

import os

# numpy's OpenBLAS starts a thread per core on import and they spin for a while: ~0.15 CPU-s of
# every node's start, and we never call BLAS (docs/ros.md, "Lost datagrams, late announcements,
# idle threads").
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
