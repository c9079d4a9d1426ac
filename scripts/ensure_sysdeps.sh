#!/usr/bin/env bash
# System packages from Debian's archive, installed when missing (as root; otherwise the command is printed):
#   libusb-1.0-0  open3d needs it at import time (required: without it this script fails)
#   chromium      tests/viz/test_html.py runs the `trumans view --html` page in it, headless (optional: the
#                 test skips without it)
set -euo pipefail
missing=()
ldconfig -p 2>/dev/null | grep -q 'libusb-1.0.so.0' || missing+=(libusb-1.0-0)
command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1 || missing+=(chromium)
if [ "${#missing[@]}" -eq 0 ]; then exit 0; fi
if [ "$(id -u)" -ne 0 ]; then
  echo "missing system packages: ${missing[*]}. Run as root:" >&2
  echo "  apt-get update && apt-get install -y ${missing[*]}" >&2
  case " ${missing[*]} " in
    *" libusb-1.0-0 "*) exit 1 ;;  # open3d cannot import without it
    *) echo "(continuing: the headless-browser test of the HTML viewer skips without chromium)" >&2 ;;
  esac
  exit 0
fi
echo "installing ${missing[*]} from Debian's packages" >&2
apt-get update -qq
DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}" >/dev/null
