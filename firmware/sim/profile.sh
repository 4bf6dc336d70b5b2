#!/bin/sh
# Map a fil_harness --profile file (byte address, samples) to functions of the ELF.
# usage: firmware/sim/profile.sh firmware.elf profile.txt
set -eu
elf=$1
prof=$2
total=$(awk '{s += $2} END {print s}' "$prof")
cut -d' ' -f1 "$prof" | avr-addr2line -f -e "$elf" | paste - - | cut -f1 |
    paste -d' ' - "$prof" |
    awk -v total="$total" '{n[$1] += $3} END {for (f in n) printf "%6.1f %%  %s\n", 100 * n[f] / total, f}' |
    sort -rn | avr-c++filt
