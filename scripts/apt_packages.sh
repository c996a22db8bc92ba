# Sourced by the install scripts: install_missing NAME PKG... installs, with apt, those of the
# Debian packages PKG... that are not installed yet (as root, or through sudo). Does nothing when
# all are there.
install_missing() {
  local name=$1; shift
  local missing=() p
  for p in "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  [ ${#missing[@]} -eq 0 ] && return 0
  local sudo=()
  if [ "$(id -u)" != 0 ]; then
    command -v sudo >/dev/null || { echo "$name: need root to install: ${missing[*]}" >&2; return 1; }
    sudo=(sudo)
  fi
  echo "$name: installing ${#missing[@]} Debian packages: ${missing[*]}"
  "${sudo[@]}" apt-get update -q
  DEBIAN_FRONTEND=noninteractive "${sudo[@]}" apt-get install -y -q --no-install-recommends "${missing[@]}"
}
