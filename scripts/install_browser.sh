#!/usr/bin/env bash
# Install Debian's Chromium and ChromeDriver for the tuning page's browser tests
# (/usr/bin/chromium, /usr/bin/chromedriver; driven by Selenium). Does nothing when present.
set -euo pipefail
source "$(dirname "$0")/apt_packages.sh"
install_missing install_browser chromium chromium-driver
