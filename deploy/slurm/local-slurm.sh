#!/bin/bash
# Starts a single-node Slurm on this machine unless one is up: installs Debian's packages
# when missing (needs root), writes /etc/slurm/slurm.conf for this node's CPUs and memory,
# starts munge, slurmctld and slurmd, and waits until the node is idle. Used by test.sh and
# for trying the recipes here (facts: Debian 12 packages, no systemd).
#
#   deploy/slurm/local-slurm.sh
set -euo pipefail
if ! command -v sbatch >/dev/null || ! command -v slurmctld >/dev/null; then
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq --no-install-recommends slurmctld slurmd slurm-client munge >/dev/null
fi
if ! scontrol ping 2>/dev/null | grep -q 'is UP'; then
    cpus=$(nproc)
    mem=$(awk '/MemTotal/ {print int($2 / 1024 * 0.9)}' /proc/meminfo)
    mkdir -p /etc/slurm /tmp/slurm/state /tmp/slurm/spool
    cat > /etc/slurm/slurm.conf <<CONF
ClusterName=ci
SlurmctldHost=localhost
SlurmUser=root
AuthType=auth/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
StateSaveLocation=/tmp/slurm/state
SlurmdSpoolDir=/tmp/slurm/spool
SlurmctldPidFile=/tmp/slurm/slurmctld.pid
SlurmdPidFile=/tmp/slurm/slurmd.pid
SlurmctldLogFile=/tmp/slurm/slurmctld.log
SlurmdLogFile=/tmp/slurm/slurmd.log
ReturnToService=2
MailProg=/bin/true
NodeName=localhost CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=debug Nodes=localhost Default=YES MaxTime=INFINITE State=UP
CONF
    install -d -o munge -g munge -m 0755 /run/munge
    [ -f /etc/munge/munge.key ] || runuser -u munge -- /usr/sbin/mungekey 2>/dev/null || true
    pgrep -x munged >/dev/null || runuser -u munge -- /usr/sbin/munged
    pgrep -x slurmctld >/dev/null || /usr/sbin/slurmctld
    for _ in $(seq 100); do scontrol ping 2>/dev/null | grep -q 'is UP' && break; sleep 0.1; done
    pgrep -x slurmd >/dev/null || /usr/sbin/slurmd
fi
for _ in $(seq 300); do sinfo -h -o %t 2>/dev/null | grep -qx idle && break; sleep 0.1; done
sinfo -h -o %t | grep -qx idle || { echo "slurm did not come up" >&2; exit 1; }

