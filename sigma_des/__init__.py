"""sigma_des: discrete-event simulation of time alignment in distributed swarm simulators."""

__version__ = "0.1.0"
