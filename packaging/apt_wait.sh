# apt_get ARGS...: apt-get run as root (sudo when needed), non-interactive, that waits for
# another apt or dpkg (unattended upgrades, a second set-up) to let go of its locks instead of
# failing at once. dpkg's lock is waited for by apt itself (DPkg::Lock::Timeout); the package
# lists' and the download cache's locks are not (apt 2.6 fails with "Could not get lock"), so
# the command is run again every APT_LOCK_POLL_S seconds until APT_LOCK_WAIT_S have passed.
# Sourced by setup.sh (bash).
apt_get() {
  local wait_s=${APT_LOCK_WAIT_S:-600} poll_s=${APT_LOCK_POLL_S:-5} said="" err sudo=""
  local deadline=$((SECONDS + wait_s))
  [ "$(id -u)" = 0 ] || sudo="sudo"
  while :; do
    if err=$($sudo env DEBIAN_FRONTEND=noninteractive apt-get -o "DPkg::Lock::Timeout=$wait_s" "$@" 2>&1 >/dev/null); then
      return 0
    fi
    if [[ $err == *"Could not get lock"* ]] && ((SECONDS < deadline)); then
      [ -n "$said" ] || echo "waiting for another apt to finish (it holds apt's lock; up to ${wait_s} s)…" >&2
      said=1
      sleep "$poll_s"
      continue
    fi
    printf '%s\n' "$err" >&2
    return 1
  done
}
