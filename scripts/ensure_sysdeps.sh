#!/usr/bin/env bash
# open3d needs libusb-1.0 at import time; install it from Debian's packages when missing.
set -euo pipefail
if ldconfig -p 2>/dev/null | grep -q 'libusb-1.0.so.0'; then exit 0; fi
if [ "$(id -u)" -ne 0 ]; then
  echo "libusb-1.0-0 is missing (open3d needs it). Run as root:" >&2
  echo "  apt-get update && apt-get install -y libusb-1.0-0" >&2
  exit 1
fi
apt-get update -qq
DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libusb-1.0-0 >/dev/null
