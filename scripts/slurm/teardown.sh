#!/usr/bin/env bash
# Stops what scripts/slurm/setup.sh started (slurmd, slurmctld, slurmdbd, mariadb, munged), jobs first.
# The packages, configs and the accounting database stay, so setup.sh starts the cluster again in seconds.
set -uo pipefail

[ "$(id -u)" -eq 0 ] || { echo "error: run as root" >&2; exit 2; }
command -v scancel >/dev/null && scancel --full --quiet --user="$(id -un)" 2>/dev/null

stop() {  # stop NAME: SIGTERM to the daemon, then wait for it to exit (SIGKILL after 20 s)
    local pids
    pids=$(pgrep -x "$1") || return 0
    kill $pids 2>/dev/null
    for _ in $(seq 20); do
        pgrep -x "$1" >/dev/null || return 0
        sleep 1
    done
    kill -9 $pids 2>/dev/null
}

stop slurmd
stop slurmctld
stop slurmdbd
command -v mysqladmin >/dev/null && mysqladmin shutdown 2>/dev/null
stop mariadbd
stop munged
echo "slurm teardown: daemons stopped"
