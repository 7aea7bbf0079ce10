"""What the world, agent and watch nodes share (ROS; the layer between the messages and the
nodes): topics and QoS (:mod:`.transport`), signing checks (:mod:`.signing`), read-only
parameters and their errors (:mod:`.params`), a node process's life — executor, spin,
one-line errors, teardown (:mod:`.run`) — and what every world and agent node does around its
runtime: readiness, liveliness, signal files, the result (:mod:`.plumbing`). No node package
imports another; they all import this.
"""
