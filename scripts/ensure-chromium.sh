#!/usr/bin/env bash
# Make sure Debian's Chromium and ChromeDriver exist for the e2e browser tests.
# Installs them with apt-get when missing and running as root; otherwise only
# explains how to install them (the e2e tests then skip) and exits 0.
set -euo pipefail

CHROMIUM=/usr/bin/chromium
DRIVER=/usr/bin/chromedriver

have() { [[ -x "$CHROMIUM" && -x "$DRIVER" ]]; }
versions() {
    echo "$("$CHROMIUM" --version 2>/dev/null || echo "$CHROMIUM"), $("$DRIVER" --version 2>/dev/null | cut -d' ' -f1-2 || echo "$DRIVER")"
}

if have; then
    echo "ensure-chromium: found $(versions)"
    exit 0
fi

if [[ "$(id -u)" -eq 0 ]]; then
    echo "ensure-chromium: chromium/chromedriver missing, installing Debian packages chromium chromium-driver ..."
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -q >/dev/null
    apt-get install -y -q chromium chromium-driver >/dev/null
    if ! have; then
        echo "ensure-chromium: apt-get finished but $CHROMIUM or $DRIVER is still missing" >&2
        exit 1
    fi
    echo "ensure-chromium: installed $(versions)"
    exit 0
fi

cat >&2 <<MSG
ensure-chromium: $CHROMIUM and/or $DRIVER not found and not running as root, so nothing was installed.
  To run the browser (e2e) tests, install them once with:
      sudo apt-get update && sudo apt-get install -y chromium chromium-driver
  Until then the tests marked e2e are skipped.
MSG
exit 0
