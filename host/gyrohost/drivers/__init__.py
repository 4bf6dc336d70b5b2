"""Device drivers of the rig host: IMU (``imu``), string servos (``servos``), wheel board.

Import the submodule you need (``from gyrohost.drivers import imu``); this package imports
nothing itself, so a missing or broken sibling never breaks the others.
"""
