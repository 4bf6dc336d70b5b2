#!/usr/bin/env bash
# Install the Debian packages the build and tests need, only those missing.
# Uses sudo when not root. Fast (one dpkg-query) when everything is present.
set -euo pipefail
packages=(gcc-avr avr-libc binutils-avr simavr libsimavr-dev libsimavrparts1 libgtest-dev cmake
          g++ make clang libclang-rt-14-dev clang-format python3-venv python3-dev)
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
