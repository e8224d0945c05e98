#!/usr/bin/env bash
# Stops the one-node cluster tools/slurm/start.sh started: slurmd,
# slurmctld and munged, by their pid files, and removes stale pid files.
set -uo pipefail
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
for p in /run/slurmd.pid /run/slurmctld.pid /run/munge/munged.pid; do
  if [ -f "$p" ]; then
    pid="$(cat "$p")"
    if kill -0 "$pid" 2>/dev/null; then
      $SUDO kill "$pid"
      for _ in $(seq 1 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    fi
    $SUDO rm -f "$p"
  fi
done
echo "slurm: stopped"
