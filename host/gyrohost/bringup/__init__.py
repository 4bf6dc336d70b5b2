"""Bringing up a real rig: serial ports found and probed, the configuration checked against the
devices (``gyrotens doctor``), servos given their IDs (``gyrotens servos id``).

- :mod:`.serialports`: every serial port with its USB identity; missing ports and permissions
  (with the ``dialout`` fix), the FTDI latency timer, the rfcomm binding.
- :mod:`.probe`: which protocol answers on a port (WT61 frames, wheel-board HELLO, Dynamixel
  PING); nothing but HELLO and PING is written, nothing moves.
- :mod:`.placeholders`: keys of the shipped lab-rig template still at their template value.
- :mod:`.doctor`: one PASS/FAIL line per check of a configuration and its devices.
- :mod:`.servo_setup`: a lone servo's ID and baud rate, a move to calibrate ``zero_position``.
"""

HELLO_TIMEOUT_S = 2.5
"""Default wait for the wheel board's HELLO reply, s: opening the Mega's port resets it, and its
bootloader runs for about two seconds before the firmware answers."""


def add_hello_timeout(parser) -> None:
    """The ``--hello-timeout S`` option of the commands that probe (argparse ``parser``); here,
    where importing costs nothing, because ``gyrotens --help`` registers every command."""
    parser.add_argument(
        "--hello-timeout",
        type=float,
        default=HELLO_TIMEOUT_S,
        metavar="S",
        help="wait for the wheel board's HELLO reply (its bootloader runs first; 2.5 s)",
    )
