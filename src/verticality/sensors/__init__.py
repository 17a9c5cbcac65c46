"""What a sensor reads given the motion: gyro, accelerometer and inclinometer readings with
their error models."""
