#!/usr/bin/env bash
# Install the Debian packages a target needs, only those missing.
#   tools/ensure-debs.sh demo   what `make demo` needs: a venv and a C compiler for the kernel
#   tools/ensure-debs.sh lab    what `make lab` needs: demo's, the AVR toolchain and avrdude
#   tools/ensure-debs.sh all    everything `make test` and `make flash` need (firmware builds,
#                               simavr, clang, avrdude)
# Uses sudo when not root. Fast (one dpkg-query) when everything is present.
set -euo pipefail
demo=(python3-venv python3-dev gcc)
case "${1:-all}" in
    demo) packages=("${demo[@]}") ;;
    lab) packages=("${demo[@]}" gcc-avr avr-libc binutils-avr avrdude make) ;;
    all) packages=("${demo[@]}" gcc-avr avr-libc binutils-avr simavr libsimavr-dev
                   libsimavrparts1 libgtest-dev cmake g++ make clang libclang-rt-14-dev
                   clang-format avrdude) ;;
    *) echo "usage: $0 demo|lab|all" >&2; exit 2 ;;
esac
missing=()
for p in "${packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0
echo "installing Debian packages: ${missing[*]}"
sudo=""
[ "$(id -u)" -ne 0 ] && sudo="sudo"
$sudo apt-get update -qq
DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
