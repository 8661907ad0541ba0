#!/usr/bin/env bash
# A single-node SLURM cluster on a Debian machine (12, bookworm: slurm-wlm 22.05), for the tests marked `slurm`
# (tests/slurm) and for trying `launcher=slurm` before a real cluster. Run as root; running it again is harmless.
#
# It installs slurm-wlm, slurmdbd, munge and mariadb-server with apt-get, writes a slurm.conf for this one
# machine (its name, CPUs and memory as found here), and starts munged, mariadb, slurmdbd, slurmctld and slurmd
# as plain daemons: no systemd is needed, so it works in a container. Accounting goes through slurmdbd into
# MariaDB, so submitit reads job states from sacct. scripts/slurm/teardown.sh stops them all again.
set -euo pipefail

[ "$(id -u)" -eq 0 ] || { echo "error: run as root (apt-get and the daemons need it)" >&2; exit 2; }
command -v apt-get >/dev/null || { echo "error: apt-get not found: this script sets up SLURM on Debian" >&2; exit 2; }

HOST=$(hostname -s)
CLUSTER=${SLURM_CLUSTER:-hybrid}
PARTITION=${SLURM_PARTITION:-debug}
CPUS=$(nproc)
MEM_MB=$(awk '/^MemTotal:/ {print int($2 / 1024)}' /proc/meminfo)
# RealMemory a little below the total: slurmd drains a node whose memory is below what slurm.conf says
REAL_MB=$((MEM_MB - MEM_MB / 20 - 256))
DB_PASS=${SLURM_DB_PASS:-slurmdb}
LOGS=/var/log/slurm

started=$(date +%s)
say() { echo "slurm setup: $*"; }

if ! command -v slurmctld >/dev/null || ! command -v slurmdbd >/dev/null || ! command -v munged >/dev/null \
    || ! command -v mariadbd >/dev/null; then
    say "installing slurm-wlm slurmdbd munge mariadb-server"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq --no-install-recommends slurm-wlm slurmdbd munge mariadb-server >/dev/null
fi

mkdir -p /etc/slurm "$LOGS" /var/spool/slurmctld /var/spool/slurmd /run/munge /var/lib/munge /var/log/munge
chown munge:munge /run/munge /var/lib/munge /var/log/munge
chmod 0755 /run/munge
if [ ! -s /etc/munge/munge.key ]; then
    dd if=/dev/urandom bs=1 count=1024 of=/etc/munge/munge.key status=none
fi
chown munge:munge /etc/munge/munge.key
chmod 0400 /etc/munge/munge.key

# the daemons run as root (SlurmUser=root): one machine, no shared spool directories to own
cat > /etc/slurm/slurm.conf <<EOF
ClusterName=$CLUSTER
SlurmctldHost=$HOST
SlurmUser=root
AuthType=auth/munge
StateSaveLocation=/var/spool/slurmctld
SlurmdSpoolDir=/var/spool/slurmd
SlurmctldPidFile=/run/slurmctld.pid
SlurmdPidFile=/run/slurmd.pid
SlurmctldLogFile=$LOGS/slurmctld.log
SlurmdLogFile=$LOGS/slurmd.log
MpiDefault=none
SwitchType=switch/none
# no cgroups in a container: processes are tracked through /proc, tasks are not bound to cores
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
ReturnToService=2
# a job cancelled or at its time limit gets SIGTERM, then KillWait seconds to save its checkpoint
KillWait=30
MinJobAge=300
AccountingStorageType=accounting_storage/slurmdbd
AccountingStorageHost=localhost
JobAcctGatherType=jobacct_gather/linux
JobCompType=jobcomp/none
NodeName=$HOST CPUs=$CPUS RealMemory=$REAL_MB State=UNKNOWN
PartitionName=$PARTITION Nodes=$HOST Default=YES MaxTime=INFINITE State=UP
EOF

cat > /etc/slurm/slurmdbd.conf <<EOF
AuthType=auth/munge
DbdHost=localhost
SlurmUser=root
PidFile=/run/slurmdbd.pid
LogFile=$LOGS/slurmdbd.log
StorageType=accounting_storage/mysql
StorageHost=localhost
StorageUser=slurm
StoragePass=$DB_PASS
StorageLoc=slurm_acct_db
EOF
chmod 0600 /etc/slurm/slurmdbd.conf

running() { pgrep -x "$1" >/dev/null; }

wait_for() {  # wait_for SECONDS DESCRIPTION COMMAND...: until the command succeeds, or fail naming what
    local limit=$1 what=$2
    shift 2
    for _ in $(seq "$limit"); do
        if "$@" >/dev/null 2>&1; then return 0; fi
        sleep 1
    done
    echo "error: $what did not come up within $limit s (logs in $LOGS)" >&2
    exit 1
}

running munged || runuser -u munge -- /usr/sbin/munged
wait_for 20 munged munge -n

if ! running mariadbd; then
    mkdir -p /run/mysqld && chown mysql:mysql /run/mysqld
    (mysqld_safe >/dev/null 2>&1 &)
fi
wait_for 60 mariadb mysqladmin ping
mysql -e "CREATE USER IF NOT EXISTS 'slurm'@'localhost' IDENTIFIED BY '$DB_PASS';
          GRANT ALL ON slurm_acct_db.* TO 'slurm'@'localhost'; FLUSH PRIVILEGES;"

running slurmdbd || slurmdbd
wait_for 60 slurmdbd sacctmgr -n list cluster
sacctmgr -i add cluster "$CLUSTER" >/dev/null 2>&1 || true
sacctmgr -i add account default Cluster="$CLUSTER" Description=default Organization=default >/dev/null 2>&1 || true
sacctmgr -i add user root Account=default DefaultAccount=default >/dev/null 2>&1 || true

running slurmctld || slurmctld
wait_for 60 slurmctld scontrol ping
running slurmd || slurmd
# a node left down by an earlier run of this script (its daemons killed) is brought back
scontrol update NodeName="$HOST" State=RESUME >/dev/null 2>&1 || true
node_idle() { sinfo -h -n "$HOST" -o %t | grep -qE '^(idle|mix|alloc)'; }
wait_for 90 "node $HOST" node_idle

say "node $HOST: $CPUS CPUs, RealMemory=$REAL_MB MB, partition $PARTITION, cluster $CLUSTER (accounting on)"
say "ready in $(($(date +%s) - started)) s"
