"""The lockstep runtime, ROS-free: how a world and N agents run a scenario step by step when each
is its own process (docs/ros.md). :mod:`.messages` what they say to each other, :mod:`.world` the
world's side (ground truth, barrier, event skipping, failures), :mod:`.agent` an agent's side
(barrier, replay of skipped steps, its plan for the next quiet steps), :mod:`.inprocess` both in
one process, :mod:`.follow` a run rebuilt from its messages (replays, the live view). The nodes
(``world_node``, ``agent_node``) carry these messages over DDS and call these classes.
"""
