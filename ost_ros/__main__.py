"""``python -m ost_ros`` runs the ``ost`` command."""

import sys

from ost_ros.cli import main

sys.exit(main())
