"""Robots without a global barrier (ROS-free): the world's bases in continuous time
(:mod:`.world`), one robot's runtime (:mod:`.agent`), the agreement layer that makes every
coordination a function of stamped messages (:mod:`.stamps`), the shared-schedule comm modules
that wait by stamp (:mod:`.comms`), a discrete-event network with seeded latencies (:mod:`.net`)
and the in-process run (:mod:`.run`, ``ost sim --latency``). docs/realtime.md."""
