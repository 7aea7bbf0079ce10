"""Object-Sorting Task (OST) protocol core — ROS-free.

Modules, one job each: ``model`` (grid, objects, agents, scenario), ``scenario`` (YAML I/O,
validation, generation), ``partition`` and ``search`` (subareas and sweeps), ``motion``,
``coordination`` (the CCP Coordination algorithm), ``agent`` (search/comm/motion FSAs),
``world`` (ground truth), ``simulator`` (in-process run), ``cli`` (the ``ost`` command).
"""

__version__ = "0.1.0"
