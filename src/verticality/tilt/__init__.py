"""Tilt from an IMU: the 3-D otolith–canal filter (gyroscope = canals, accelerometer = otoliths),
its offline smoother, its real-time form, the estimation of recordings and folders, and the
evaluations on BROAD and on synthetic recordings (docs/tilt.md)."""
