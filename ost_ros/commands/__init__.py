"""The ``ost`` command's verbs (ost_ros/cli.py dispatches to them)."""

import os

# Before numpy is imported (also by a caller that imports a verb's module without the CLI): its
# OpenBLAS threads cost ~0.15 CPU-s of every start, no verb calls BLAS, and a supervisor forks
# robots only while it has one thread (spawn.py).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
