"""What CCP and NCP share: the knowledge every agent holds alike (found objects, the global
schedule, when and where each agent is free) and the agent that executes such a schedule."""
