"""Motions and the closed loop: trajectories (built in or recorded), the head's controllers, the
simulator that runs plant, sensors, estimator and controller together, and head stabilization."""
