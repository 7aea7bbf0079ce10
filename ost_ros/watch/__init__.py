"""Watching a run: frames recorded by a step hook (:mod:`.frames`) and the animation drawn from
them (:mod:`.animate`). ROS-free; recordings (MCAP) live in :mod:`ost_msgs_py.bag` and their
replay in :mod:`ost_msgs_py.replay` (the world's bookkeeping fed the recorded messages,
:mod:`ost_ros.lockstep.follow`)."""
