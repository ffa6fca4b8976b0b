#!/usr/bin/env bash
# A single-node Slurm cluster on this machine, for the batch tests: no systemd, as root,
# on localhost, from Debian's slurmctld, slurmd, slurm-client and munge.
#
#   scripts/slurm-local.sh start   # prints the SLURM_CONF to export
#   scripts/slurm-local.sh stop
#
# State, logs and the configuration live in $SLURM_LOCAL_DIR (default
# /tmp/goniospec-slurm). Settings that work on machines without cgroups (measured):
# proctrack/linuxproc, task/none, no job accounting; a small MinJobAge so `sbatch --wait`
# returns within seconds.
set -euo pipefail
D=${SLURM_LOCAL_DIR:-/tmp/goniospec-slurm}
conf=$D/slurm.conf

die() { echo "slurm-local: $*" >&2; exit 1; }

start() {
  [ "$(id -u)" = 0 ] || die "needs root (Slurm's daemons run as root here)"
  for b in slurmctld slurmd sbatch munged; do
    command -v "$b" >/dev/null || die "$b not found: apt-get install slurmctld slurmd slurm-client munge"
  done
  mkdir -p "$D/state" "$D/spool"
  # munge: a key of mode 0400 owned by munge, and /run/munge made by hand.
  if [ ! -s /etc/munge/munge.key ]; then
    mkdir -p /etc/munge
    dd if=/dev/urandom of=/etc/munge/munge.key bs=1 count=1024 status=none
  fi
  chown munge:munge /etc/munge/munge.key
  chmod 0400 /etc/munge/munge.key
  mkdir -p /run/munge /var/log/munge /var/lib/munge
  chown munge:munge /run/munge /var/log/munge /var/lib/munge
  if ! pgrep -x munged >/dev/null; then
    runuser -u munge -- munged
  fi
  local node
  node=$(slurmd -C | head -1)
  cat > "$conf" <<CONF
ClusterName=goniospec
SlurmctldHost=localhost
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
StateSaveLocation=$D/state
SlurmdSpoolDir=$D/spool
SlurmctldPidFile=$D/slurmctld.pid
SlurmdPidFile=$D/slurmd.pid
SlurmctldLogFile=$D/slurmctld.log
SlurmdLogFile=$D/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
MinJobAge=5
ReturnToService=2
$node NodeAddr=127.0.0.1 State=UNKNOWN
PartitionName=batch Nodes=ALL Default=YES MaxTime=INFINITE State=UP
CONF
  export SLURM_CONF=$conf
  slurmctld -f "$conf"
  slurmd -f "$conf"
  for _ in $(seq 1 60); do
    if sinfo -h -o %T 2>/dev/null | grep -qE '^(idle|mixed|allocated)'; then
      echo "SLURM_CONF=$conf"
      return 0
    fi
    sleep 0.5
  done
  tail -5 "$D/slurmctld.log" "$D/slurmd.log" >&2 || true
  die "the node did not come up"
}

stop() {
  if [ -f "$conf" ]; then
    SLURM_CONF=$conf scancel --user=root 2>/dev/null || true
  fi
  for p in "$D/slurmd.pid" "$D/slurmctld.pid"; do
    if [ -s "$p" ]; then kill "$(cat "$p")" 2>/dev/null || true; fi
  done
  sleep 1
  for p in "$D/slurmd.pid" "$D/slurmctld.pid"; do
    if [ -s "$p" ]; then kill -9 "$(cat "$p")" 2>/dev/null || true; rm -f "$p"; fi
  done
}

case "${1:-}" in
  start) start ;;
  stop) stop ;;
  *) die "usage: $0 start|stop" ;;
esac
