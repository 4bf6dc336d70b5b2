"""Column names of the run-log streams the estimator reads and writes: the one place they live.

The run loop writes the input streams with these columns (``gyrohost.run.log``); ``gyrotens
replay`` and the estimator read them back; the output streams are written by
:mod:`.replay`. Every time column is ``t_s``: host time since the start of the run, s.

Input streams
    ``imu``: ``t_s``, rate ``omega_{x,y,z}_rad_s``, specific force ``accel_{x,y,z}_m_s2``,
    angles ``roll_rad, pitch_rad, yaw_rad`` (Z-Y-X, sensor axes, as the IMU driver gives them).
    ``wheels``: ``t_s``, ``omega_<i>_rad_s`` for board wheels i = 0..3 (scene wheel order).
    ``servos``: ``t_s``, ``<string>_length_m`` for every scene string a servo winds.
    ``command``: ``t_s``, ``<string>_rest_m`` for every scene string (commanded rest length),
    ``omega_cmd_<i>_rad_s`` for board wheels i = 0..3; stamped at the tick that made them.
    ``servo_goals``: ``t_s``, ``<string>_rest_m`` for every scene string: the rest lengths the
    servos were sent, stamped when they went onto the bus (a goal leaves up to a few
    milliseconds after its tick); the estimator's rest-length input where a log has it.

Output streams
    ``estimate``: ``t_s, status`` then the state (:meth:`FilterLayout.labels`), the standard
    deviation of each (``std_`` prefix), ``roll_rad, pitch_rad, yaw_rad, tilt_rad``.
    ``innov_<source>`` for each source: ``t_s``, ``y_<c>`` innovation and ``var_<c>`` its
    variance per component ``c``, ``nis``, ``test_ratio``, ``accepted``, ``rejected_count``.
"""

BOARD_WHEELS = 4
IMU = "imu"
WHEELS = "wheels"
WHEEL_DEVICE_TIME = "device_t_us"  # the board's own clock at the sample, us
SERVOS = "servos"
COMMAND = "command"
SERVO_GOALS = "servo_goals"
ESTIMATE = "estimate"
TRUTH = "truth"  # the simulated rig's, scored by a replay (gyrohost.run.replay)
IMU_RATE = ("omega_x_rad_s", "omega_y_rad_s", "omega_z_rad_s")
IMU_ACCEL = ("accel_x_m_s2", "accel_y_m_s2", "accel_z_m_s2")
IMU_ANGLE = ("roll_rad", "pitch_rad", "yaw_rad")


def imu_columns() -> list[str]:
    return ["t_s", *IMU_RATE, *IMU_ACCEL, *IMU_ANGLE]


def wheel_speed_columns(n: int = BOARD_WHEELS) -> list[str]:
    return [f"omega_{i}_rad_s" for i in range(n)]


def wheel_command_columns(n: int = BOARD_WHEELS) -> list[str]:
    return [f"omega_cmd_{i}_rad_s" for i in range(n)]


def wheels_columns(n: int = BOARD_WHEELS) -> list[str]:
    return ["t_s", *wheel_speed_columns(n)]


def servo_length_column(string: str) -> str:
    return f"{string}_length_m"


def servos_columns(strings) -> list[str]:
    """``strings``: names of the scene strings the servos wind, in servo order."""
    return ["t_s", *(servo_length_column(s) for s in strings)]


def rest_column(string: str) -> str:
    return f"{string}_rest_m"


def command_columns(strings, n_wheels: int = BOARD_WHEELS) -> list[str]:
    """``strings``: all scene strings, scene order."""
    return ["t_s", *(rest_column(s) for s in strings), *wheel_command_columns(n_wheels)]


def goals_columns(strings) -> list[str]:
    """``strings``: all scene strings, scene order."""
    return ["t_s", *(rest_column(s) for s in strings)]


def rest_goals(data: dict) -> str:
    """The name of the stream of ``data`` (stream name -> rows) whose ``<string>_rest_m``
    columns are the servos' goals: ``servo_goals`` where the log has rows of it, else
    ``command`` (logs made before it)."""
    goals = data.get(SERVO_GOALS)
    return SERVO_GOALS if goals is not None and len(goals) else COMMAND


def estimate_columns(state_labels) -> list[str]:
    labels = list(state_labels)
    return ["t_s", "status", *labels, *(f"std_{c}" for c in labels), *IMU_ANGLE, "tilt_rad"]


def innovation_stream(source: str) -> str:
    return f"innov_{source}"


def innovation_columns(components) -> list[str]:
    comps = list(components)
    return [
        "t_s",
        *(f"y_{c}" for c in comps),
        *(f"var_{c}" for c in comps),
        "nis",
        "test_ratio",
        "accepted",
        "rejected_count",
    ]
