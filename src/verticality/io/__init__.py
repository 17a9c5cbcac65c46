"""Reading and writing files: head motions (``motion``), IMU recordings (``imu``), BROAD
(``broad``)."""
