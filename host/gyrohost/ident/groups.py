"""The parameter groups ``gyrotens identify`` can fit, by name.

Apart from :mod:`gyrohost.ident.params` so that registering the command imports neither numpy
nor the model (``gyrotens --help`` stays fast).
"""

GROUPS = {
    "J3": "one shared factor on every wheel's axial inertia J3",
    "J3-each": "each wheel's J3 on its own",
    "bar-mass": "one factor on every bar's mass (its transverse inertia follows, m l^2 / 12)",
    "bar-inertia": "one factor on every bar's transverse inertia, apart from its mass",
    "stiffness": "one factor on every string's stiffness",
    "damping": "one factor on every string's damping",
    "mounting": "the IMU's mounting rotation (roll, pitch, yaw of the sensor axes, rad)",
    "gyro-bias": "the gyro's bias (x, y, z, rad/s)",
    "accel-bias": "the accelerometer's bias (x, y, z, m/s^2)",
    "servo-offsets": "each string servo's zero offset (m added to its reported length)",
    "servo-lag": "the first-order lag to a string's rest length (s) from its servo's reported "
    "position, or with commanded lengths from the command",
    "imu-latency": "the IMU's latency from taking a sample to its stamp (s)",
    "process-noise": "one factor on the filter's node-acceleration noise accel_psd_m2_s3 "
    "(--method filter)",
}
FILTER_GROUPS = ("process-noise",)
"""Groups of the filter's own model: fitted by its likelihood (``--method filter``) only. The
noise scale sets how far the filter trusts its model; the likelihood's ``log det S`` term keeps
it from buying a small NIS with a wide ``S``."""
DEFAULT_GROUPS = (
    "J3", "stiffness", "damping", "mounting", "gyro-bias", "accel-bias", "imu-latency",
)  # fmt: skip
"""With ``imu-latency``: a sensor that stamps its samples late shows the structure's response
later than the model does, and a fit without it reads the delay as extra damping. Without
``bar-mass``: the D-bar's motion fixes J3, stiffness and damping relative to the bar mass; the
absolute scale rests on the wheels' mass alone and is not resolved in practice
(docs/identification.md): weigh the bars and give their mass in the scene."""
