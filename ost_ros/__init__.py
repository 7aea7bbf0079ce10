"""Object-Sorting Task (OST) core — ROS-free.

Modules, one job each: ``model`` (grid, objects, agents, scenario), ``scenario`` (YAML I/O,
validation, generation), ``partition`` and ``search`` (subareas and sweeps), ``motion``,
``coordination`` (Algorithm Coordination and its triggers), ``world`` (ground truth);
``protocols`` (the registry and one sub-package per cooperation protocol), ``engines`` (step,
event and analytic runs: ``engines.simulate``), ``negotiation`` (Rossi et al.'s library),
``cli`` and ``commands`` (the ``ost`` command). docs/architecture.md has the map.
"""

__version__ = "0.1.0"
