#!/usr/bin/env bash
# Debian packages only the tests need (not the library): Chromium for the web viewer's browser
# test (tests/web/test_browser.py; about 100 MB, so it is not part of install-system-deps.sh).
# Set LBSCENE_NO_CHROMIUM=1 to skip it: the browser test then skips with its reason.
set -euo pipefail
[ "${LBSCENE_NO_CHROMIUM:-0}" = 1 ] && exit 0
if command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1; then
  exit 0
fi
echo "installing Debian package: chromium (for the web viewer's browser test)"
SUDO=""; [ "$(id -u)" = 0 ] || SUDO="sudo"
$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq chromium
