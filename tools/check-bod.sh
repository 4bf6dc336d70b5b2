#!/bin/sh
# check-bod.sh PORT PROGRAMMER - before `make flash`: read the wheel board's extended fuse through
# its bootloader (the stk500v2 bootloader answers fuse reads) and refuse a board whose brown-out
# detector is not at 4.3 V (docs/hardware.md, "Brown-out"). Exit 0 ok, 1 refused, 2 bad usage.
set -u
if [ $# -ne 2 ]; then
    echo "usage: tools/check-bod.sh PORT PROGRAMMER" >&2
    exit 2
fi
port=$1
programmer=$2
if ! efuse=$(avrdude -q -q -p atmega2560 -c "$programmer" -P "$port" -b 115200 \
    -U efuse:r:-:h 2>/dev/null); then
    echo "make flash: cannot read the extended fuse of the board on $port (avrdude failed:" \
        "the port, a board in its bootloader, PROGRAMMER=$programmer?)" >&2
    exit 1
fi
case $efuse in
0x[0-9a-fA-F] | 0x[0-9a-fA-F][0-9a-fA-F]) ;;
*)
    echo "make flash: avrdude read the extended fuse of the board on $port as '$efuse'," \
        "not a byte" >&2
    exit 1
    ;;
esac
# BODLEVEL is bits 2..0 of the extended fuse: 100 = 4.3 V (101 2.7 V, the Arduino default;
# 111 off); the other bits are unused and read as 0 or 1 depending on the avrdude version.
if [ $((efuse & 7)) -ne 4 ]; then
    echo "make flash: the board on $port has extended fuse $efuse: its brown-out detector is" \
        "not at 4.3 V (BODLEVEL, bits 2..0, must be 100). A bootloader cannot write fuses: set" \
        "it with an ISP programmer, e.g. avrdude -p atmega2560 -c usbasp -U efuse:w:0xFC:m" \
        "(docs/hardware.md, \"Brown-out\"), then flash again." >&2
    exit 1
fi
