#!/usr/bin/env bash
# Starts a one-node Slurm cluster on this machine for omcl's tests:
# installs Slurm and munge from the Debian packages where missing, writes
# /etc/slurm/slurm.conf from tools/slurm/slurm.conf.in and starts munged,
# slurmctld and slurmd by hand (no systemd). Idempotent: a running cluster
# is left as it is. Exits non-zero, printing the daemons' logs, if the node
# does not come up.
#
#   OMCL_SLURM_STATE   state and log folder (default /var/lib/omcl-slurm)
#   OMCL_SLURM_MAX_ARRAY  MaxArraySize (default 1001, Slurm's default)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
STATE="${OMCL_SLURM_STATE:-/var/lib/omcl-slurm}"
MAX_ARRAY="${OMCL_SLURM_MAX_ARRAY:-1001}"
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"

logs() {
  for f in "$STATE/slurmctld.log" "$STATE/slurmd.log" /var/log/munge/munged.log; do
    [ -f "$f" ] && { echo "---- $f (last 40 lines)"; tail -n 40 "$f"; }
  done
  return 0
}
fail() { echo "slurm: $*" >&2; logs >&2; exit 1; }

need=()
command -v munged >/dev/null 2>&1 || need+=(munge)
command -v slurmctld >/dev/null 2>&1 || need+=(slurmctld)
command -v slurmd >/dev/null 2>&1 || need+=(slurmd)
command -v sbatch >/dev/null 2>&1 || need+=(slurm-client)
if [ ${#need[@]} -gt 0 ]; then
  echo "slurm: installing Debian packages: ${need[*]}"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null \
    || fail "apt-get install ${need[*]} failed"
fi

host="$(hostname -s)"
cpus="$(nproc)"
mem_mb=$(( $(awk '/MemTotal/ {print $2}' /proc/meminfo) / 1024 * 9 / 10 ))
$SUDO mkdir -p /etc/slurm "$STATE/ctld" "$STATE/d"
conf="$(sed -e "s|@HOST@|$host|g" -e "s|@CPUS@|$cpus|g" -e "s|@MEM@|$mem_mb|g" \
  -e "s|@STATE@|$STATE|g" -e "s|@MAX_ARRAY@|$MAX_ARRAY|g" "$here/slurm.conf.in")"
if ! [ -f /etc/slurm/slurm.conf ] || [ "$conf" != "$(cat /etc/slurm/slurm.conf)" ]; then
  printf '%s\n' "$conf" | $SUDO tee /etc/slurm/slurm.conf >/dev/null
  changed=yes
else
  changed=no
fi

alive() { [ -f "$1" ] && kill -0 "$(cat "$1")" 2>/dev/null; }

# munge: a key (the package makes one; make it if missing), /run/munge
# owned by munge, the daemon run as user munge.
if [ ! -f /etc/munge/munge.key ]; then
  $SUDO mkdir -p /etc/munge
  $SUDO dd if=/dev/urandom of=/etc/munge/munge.key bs=1024 count=1 status=none
  $SUDO chown munge:munge /etc/munge/munge.key
  $SUDO chmod 400 /etc/munge/munge.key
fi
if ! alive /run/munge/munged.pid; then
  $SUDO mkdir -p /run/munge /var/log/munge /var/lib/munge
  $SUDO chown munge:munge /run/munge /var/log/munge /var/lib/munge
  if [ "$(id -u)" -eq 0 ]; then
    runuser -u munge -- /usr/sbin/munged || fail "munged did not start"
  else
    sudo -u munge /usr/sbin/munged || fail "munged did not start"
  fi
fi

# A changed configuration restarts the Slurm daemons. The old ones must
# be gone before the new ones start: a slurmd started while the old one
# still holds its port exits at once, before it writes to its log (seen
# on a machine whose cluster an earlier run had started).
if [ "$changed" = yes ]; then
  for p in /run/slurmd.pid /run/slurmctld.pid; do
    if alive "$p"; then
      pid="$(cat "$p")"
      $SUDO kill "$pid"
      for _ in $(seq 1 60); do kill -0 "$pid" 2>/dev/null || break; sleep 0.25; done
    fi
  done
fi
start() {
  if ! alive "/run/$1.pid"; then
    $SUDO rm -f "/run/$1.pid"
    $SUDO "/usr/sbin/$1" || fail "$1 did not start"
  fi
}
start slurmctld
start slurmd

# Wait for the node to be idle (or allocated/mixed: busy from an earlier
# run), starting slurmd again if it has exited meanwhile.
for i in $(seq 1 60); do
  state="$(sinfo -h -N -o '%T' 2>/dev/null | head -1 || true)"
  case "$state" in
    idle*|alloc*|mix*) echo "slurm: node $host is $state ($cpus CPUs, MaxArraySize=$MAX_ARRAY)"; exit 0 ;;
    down*|drain*) $SUDO scontrol update nodename="$host" state=resume >/dev/null 2>&1 || true ;;
  esac
  if [ $((i % 4)) -eq 0 ] && ! alive /run/slurmd.pid; then
    echo "slurm: slurmd exited; starting it again" >&2
    start slurmd
  fi
  sleep 0.5
done
fail "node $host did not become idle (state: ${state:-none})"
