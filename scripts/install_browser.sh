#!/usr/bin/env bash
# Install Debian's Chromium and ChromeDriver for the tuning page's browser tests
# (/usr/bin/chromium, /usr/bin/chromedriver; driven by Selenium). Does nothing when present.
set -euo pipefail
PACKAGES=(chromium chromium-driver)
missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
[ ${#missing[@]} -eq 0 ] && exit 0
as_root() {
  if [ "$(id -u)" = 0 ]; then "$@"; elif command -v sudo >/dev/null; then sudo "$@"; else
    echo "install_browser: need root to run: $*" >&2; return 1; fi
}
echo "install_browser: installing ${missing[*]}"
as_root apt-get update -q
DEBIAN_FRONTEND=noninteractive as_root apt-get install -y -q --no-install-recommends "${missing[@]}"
