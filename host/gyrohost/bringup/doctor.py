"""``gyrotens doctor``: a rig configuration checked against itself and its devices, one line per
item (docs/bring-up.md): PASS; WARN for what a run takes but should be measured (a datasheet
figure, a lag not yet fitted, a dimension still at the template's value); FAIL for what blocks a
run (a port missing, a wheel offset uncalibrated, a placeholder the run refuses).

The devices are opened and identified with the probes of :mod:`.probe` (IMU frames listened to,
HELLO to the wheel board, PING to each configured servo). The wheel board is asked which
offsets it holds with a 1 mrad/s setpoint per wheel (:func:`.wheels.uncalibrated_wheels`): the
drive stays at zero, nothing turns.
"""

import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from gyrohost.bringup import HELLO_TIMEOUT_S, probe
from gyrohost.bringup.placeholders import find_placeholders
from gyrohost.bringup.serialports import (
    SYS,
    access_problem,
    latency_timer_fix,
    latency_timer_ms,
    rfcomm_bound,
)
from gyrohost.drivers import wheelproto as wp
from gyrohost.drivers.errors import PortBusyError, ServoLimitError
from gyrohost.drivers.mx12 import MODEL_MX12W
from gyrohost.drivers.servos import StringServoBus

from .errors import WheelSetupError
from .wheels import uncalibrated_wheels

PLACEHOLDER = "placeholder"
IMU_BAUD_FOR_RATE = {100: 115200, 20: 9600}
"""The BWT61CL's output rate, Hz -> the baud rate that carries it."""


PASS, WARN, FAIL = "PASS", "WARN", "FAIL"


@dataclass(frozen=True)
class Check:
    """One check: its name, its level (PASS, WARN or FAIL), what was found (and the fix)."""

    name: str
    level: str
    detail: str

    def __post_init__(self):
        if self.level not in (PASS, WARN, FAIL):  # a bool would read as "not FAIL"
            raise ValueError(f"check {self.name!r}: level {self.level!r} is not PASS, WARN or FAIL")

    @classmethod
    def of(cls, name: str, ok: bool, detail: str) -> "Check":
        """PASS when ``ok``, else FAIL."""
        return cls(name, PASS if ok else FAIL, detail)

    @property
    def ok(self) -> bool:
        """Nothing here blocks a run (PASS or WARN)."""
        return self.level != FAIL

    def line(self) -> str:
        """``PASS  name: detail``."""
        return f"{self.level}  {self.name}: {self.detail}"


@dataclass(frozen=True)
class Windows:
    """How long the doctor listens and how close it wants the IMU's rate.

    Attributes
    ----------
    imu_s : float, s
        IMU rate measured over this window.
    hello_s : float, s
        Wait for the wheel board's HELLO reply.
    imu_rate_tolerance : float
        The measured IMU rate may differ from ``imu.rate_hz`` by this fraction (Bluetooth
        bunches samples; a loaded machine serving emulators falls behind).
    """

    imu_s: float = 1.0
    hello_s: float = HELLO_TIMEOUT_S
    imu_rate_tolerance: float = 0.2


def run_checks(config, sys_root: Path = SYS, windows: Windows = Windows()) -> Iterator[Check]:
    """Every check of ``config`` (a loaded ``RigConfig``) and its devices, in order."""
    yield from _placeholders(config)
    yield _limits(config)
    yield from _unless_held("imu", _imu(config, sys_root, windows))
    yield from _unless_held("wheel board", _wheelboard(config, windows))
    yield from _unless_held("servos", _servos(config, sys_root))


def _unless_held(name: str, checks: Iterator[Check]) -> Iterator[Check]:
    """A device's ``checks``; a port another process holds (a run under way) ends them with one
    failed check naming the holder (:mod:`gyrohost.drivers.portlock`)."""
    try:
        yield from checks
    except PortBusyError as exc:
        yield Check(name, FAIL, str(exc))


def _placeholders(config) -> Iterator[Check]:
    if not config.source.endswith(".toml"):
        yield Check(PLACEHOLDER, PASS, "no configuration file to compare")
        return
    found = find_placeholders(config.source)
    if not found:
        yield Check(PLACEHOLDER, PASS, "no MEASURE or CALIBRATE key at its template value")
    for p in found:
        if p.required:
            yield Check(PLACEHOLDER, FAIL, f"{p.describe()}; 'gyrotens run' refuses it")
        else:
            yield Check(PLACEHOLDER, WARN, f"{p.describe()}; a run takes it until measured")


def contradictions(config) -> list[str]:
    """Limits of ``config`` that contradict each other or the scene, one sentence each."""
    from gyrotensegrity import load_scene

    problems = []
    imu = config.imu
    if IMU_BAUD_FOR_RATE[imu.rate_hz] != imu.baud:
        problems.append(
            f"imu.rate_hz = {imu.rate_hz} needs imu.baud = {IMU_BAUD_FOR_RATE[imu.rate_hz]}, "
            f"not {imu.baud}"
        )
    try:
        StringServoBus(config.servos)  # checks each servo's ranges; opens nothing
    except ServoLimitError as exc:
        problems.append(str(exc))
    rest = {s.name: s.rest_length(0.0) for s in load_scene(config.scene_path).strings}
    for i, servo in enumerate(config.servos.servo):
        length = rest.get(servo.string)
        if length is not None and not servo.min_length_m <= length <= servo.max_length_m:
            problems.append(
                f"servos.servo[{i}]: the scene starts string {servo.string} at {length:.4f} m, "
                f"outside [min_length_m, max_length_m] = [{servo.min_length_m:g}, "
                f"{servo.max_length_m:g}] m"
            )
    return problems


def _limits(config) -> Check:
    found = contradictions(config)
    if found:
        return Check("limits", FAIL, "; ".join(found))
    tilt = config.run.max_tilt_rad
    tilt_text = "unchecked" if math.isinf(tilt) else f"{tilt:g} rad"
    return Check(
        "limits", PASS, f"consistent (servo ranges hold the scene's start; tilt {tilt_text})"
    )


def _access(key: str, port: str) -> Check:
    problem = access_problem(port)
    return Check.of(f"{key} {port}", problem is None, problem or "present, readable and writable")


def _imu(config, sys_root: Path, windows: Windows) -> Iterator[Check]:
    port = config.imu.port
    name = Path(port).resolve().name  # a udev link to /dev/rfcomm0 is an rfcomm port too
    if name.startswith("rfcomm"):
        if not rfcomm_bound(name, sys_root):  # then its port cannot exist: one failure, not two
            fix = f"sudo rfcomm bind {name[6:]} <BWT61CL address> 1 (docs/bring-up.md)"
            yield Check("imu rfcomm", FAIL, f"{name} not bound: {fix}")
            return
        yield Check("imu rfcomm", PASS, f"{name} bound")
    access = _access("imu.port", port)
    yield access
    if not access.ok:
        return
    with probe.open_serial(port, config.imu.baud) as ser:
        rate_hz = probe.listen_wt61(ser, windows.imu_s)
    off = abs(rate_hz - config.imu.rate_hz) / config.imu.rate_hz
    detail = f"BWT61CL frames at {rate_hz:.1f} Hz over {windows.imu_s:g} s"
    if rate_hz == 0:
        detail = f"no WT61 frame in {windows.imu_s:g} s at {config.imu.baud} baud"
    elif off > windows.imu_rate_tolerance:
        detail += f", configured imu.rate_hz = {config.imu.rate_hz}"
    yield Check.of("imu", rate_hz > 0 and off <= windows.imu_rate_tolerance, detail)


def _wheelboard(config, windows: Windows) -> Iterator[Check]:
    access = _access("wheelboard.port", config.wheelboard.port)
    yield access
    if not access.ok:
        return
    with probe.open_serial(config.wheelboard.port, config.wheelboard.baud) as ser:
        fields = probe.hello(ser, windows.hello_s)
        if fields is None:
            detail = (
                f"no HELLO reply in {windows.hello_s:g} s (flashed? 'make flash', docs/bring-up.md)"
            )
            yield Check("wheel board", FAIL, detail)
            return
        same = fields["proto_version"] == wp.PROTO_VERSION
        yield Check.of("wheel board", same, probe.describe_hello(fields))
        if same:
            yield _offsets(ser)


def _offsets(ser) -> Check:
    """Which wheels the board refuses to run for their default offset (the port stays open:
    opening it again would reset the Mega)."""
    from gyrohost.drivers.wheelboard import WheelBoard

    board = WheelBoard(ser, reply_timeout_s=1.0)
    try:
        board.connect()
        refused = uncalibrated_wheels(board)
    except WheelSetupError as exc:
        return Check("wheel offsets", WARN, str(exc))
    finally:
        board.close()
    if refused:
        fixes = "; ".join(f"gyrotens wheels calibrate --wheel {w}" for w in refused)
        return Check("wheel offsets", FAIL, f"wheels {refused} uncalibrated: {fixes}")
    return Check("wheel offsets", PASS, f"all {wp.N_WHEELS} calibrated")


def _servos(config, sys_root: Path) -> Iterator[Check]:
    bus = config.servos
    access = _access("servos.port", bus.port)
    yield access
    if not access.ok:
        return
    latency = latency_timer_ms(bus.port, sys_root)
    if latency is None:
        yield Check("servos latency timer", PASS, "no FTDI latency timer on this port")
    else:
        fix = "" if latency == 1 else f" (1 ms wanted: {latency_timer_fix(bus.port, sys_root)})"
        yield Check.of("servos latency timer", latency == 1, f"{latency} ms{fix}")
    ids = [s.id for s in bus.servo]
    found = probe.ping_ids(bus.port, bus.baud, ids, bus.reply_timeout_s)
    missing = [i for i in ids if i not in found]
    wrong = {i: m for i, m in found.items() if m != MODEL_MX12W}
    answered = ", ".join(f"ID {i} {probe.model_name(m)}" for i, m in found.items()) or "none"
    detail = f"answered at {bus.baud} baud: {answered}"
    if missing:
        detail += f"; no reply from ID {', '.join(map(str, missing))} ('gyrotens ports' scans)"
    if wrong:
        detail += f"; not an MX-12W (model {MODEL_MX12W}): {sorted(wrong)}"
    yield Check.of("servos", not missing and not wrong, detail)
