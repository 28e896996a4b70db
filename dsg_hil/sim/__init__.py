"""A run in time: the scenario, the plant's CAN edge, the plant runner (lockstep and real time), the closed loop."""
