#!/usr/bin/env bash
# Starts a one-node Slurm (Debian's slurm-wlm and munge) on this machine for testing the scripts
# here; prints the environment to use it (SLURM_CONF). Needs root (the daemons). Stop it with
# `deploy/slurm/local-cluster.sh stop DIR`.
#   eval "$(deploy/slurm/local-cluster.sh start /tmp/vtgen-slurm)"
set -euo pipefail
cmd="${1:?usage: $0 start|stop DIR}"
dir="$(realpath -m "${2:?usage: $0 start|stop DIR}")"
if [ "$cmd" = stop ]; then
  for p in slurmd slurmctld munged; do
    [ -f "$dir/$p.pid" ] && kill "$(cat "$dir/$p.pid")" 2>/dev/null || true
  done
  # The daemons write their state as they shut down: wait (up to 10 s each) until they are gone,
  # so that the caller can remove DIR.
  for p in slurmd slurmctld munged; do
    pid="$(cat "$dir/$p.pid" 2>/dev/null || true)"
    for _ in $(seq 50); do
      [ -n "$pid" ] && kill -0 "$pid" 2>/dev/null || break
      sleep 0.2
    done
  done
  exit 0
fi
[ "$(id -u)" = 0 ] || { echo "local-cluster.sh: the Slurm daemons need root" >&2; exit 3; }
for b in slurmctld slurmd munged sbatch; do
  command -v "$b" >/dev/null || { echo "local-cluster.sh: $b is missing (apt-get install slurm-wlm munge)" >&2; exit 3; }
done
mkdir -p "$dir"/{spool,state,munge,log}
chmod 755 "$dir" "$dir/munge"
host="$(hostname -s)"
cpus="$(nproc)"
mem=$(( $(awk '/MemTotal/ {print $2}' /proc/meminfo) / 1024 - 512 ))
# munge: its own key, socket and pid file under DIR (no system service needed).
[ -f "$dir/munge/munge.key" ] || head -c 1024 /dev/urandom > "$dir/munge/munge.key"
chmod 400 "$dir/munge/munge.key"
munged --force --key-file="$dir/munge/munge.key" --socket="$dir/munge/socket" \
  --pid-file="$dir/munged.pid" --log-file="$dir/log/munged.log" --seed-file="$dir/munge/seed"
cat > "$dir/slurm.conf" <<CONF
ClusterName=vtgen-test
SlurmctldHost=$host
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$dir/munge/socket
CredType=cred/munge
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
SlurmctldPort=16817
SlurmdPort=16818
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
MaxArraySize=1001
JobRequeue=0
NodeName=$host CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=test Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF="$dir/slurm.conf"
slurmctld -c -f "$SLURM_CONF"
slurmd -f "$SLURM_CONF"
for _ in $(seq 60); do
  if sinfo -h -o %t 2>/dev/null | grep -qE '^(idle|mix|alloc)'; then
    echo "export SLURM_CONF=$SLURM_CONF"
    exit 0
  fi
  sleep 1
done
echo "local-cluster.sh: the node did not come up; see $dir/log" >&2
sinfo >&2 || true
tail -n 20 "$dir"/log/*.log >&2 || true
exit 4
