"""``gyrotens ports [--no-probe] [PATH ...]``: every serial port, what answers on it, and the
configuration lines to paste (docs/bring-up.md). Probing writes only HELLO and PING: nothing
moves. A PATH given that is missing or cannot be probed is bad input (exit 2)."""

import sys

from gyrohost.bringup import add_hello_timeout


def register(sub) -> None:
    p = sub.add_parser(
        "ports", help="list the serial ports, probe each for the IMU, wheel board and servos"
    )
    p.add_argument("paths", nargs="*", metavar="PATH", help="more ports to probe (ptys, ...)")
    p.add_argument("--no-probe", action="store_true", help="list only, open nothing")
    add_hello_timeout(p)
    p.add_argument(
        "--reply-timeout",
        type=float,
        default=0.034,
        metavar="S",
        help="wait for each servo's reply to PING beyond its transfer time (0.034 s)",
    )
    p.set_defaults(func=run)


def run(args) -> int:
    from gyrohost.bringup.probe import probe
    from gyrohost.bringup.serialports import access_problem, list_ports
    from gyrohost.commands.errors import CliError
    from gyrohost.drivers.errors import PortBusyError

    for path in args.paths:  # a port named on the command line must be there
        problem = access_problem(path)
        if problem is not None:
            raise CliError(f"{path}: {problem}")
    unprobed = []
    ports = list_ports(tuple(args.paths))
    if not ports:
        print("no serial port found (plugged in? 'dmesg | tail' shows what the kernel saw)")
        return 1
    config_lines = []
    for info in ports:
        usb = f" USB {info.vid_pid}" if info.vid_pid else ""
        desc = f" {info.description}" if info.description else ""
        print(f"{info.device}{usb}{desc}")
        if info.by_id:
            print(f"  by-id: {info.by_id}")
        if args.no_probe:
            continue
        problem = access_problem(info.device)
        if problem is not None:
            print(f"  cannot probe: {problem}")
            continue
        try:
            result = probe(
                info.stable_path,
                hello_timeout_s=args.hello_timeout,
                reply_timeout_s=args.reply_timeout,
            )
        except (OSError, PortBusyError) as exc:  # busy, vanished: say so, go on with the next
            print(f"  cannot probe: {exc}")
            if info.device in args.paths:
                unprobed.append(f"{info.device}: {exc}")
            continue
        print(f"  {result.detail}")
        if result.config_lines:
            config_lines += ["", *result.config_lines]
    if config_lines:
        print("\nconfiguration lines to paste (docs/rig-config.md):")
        print("\n".join(config_lines[1:]))
    sys.stdout.flush()
    if unprobed:
        raise CliError(f"cannot probe {'; '.join(unprobed)}")
    return 0
