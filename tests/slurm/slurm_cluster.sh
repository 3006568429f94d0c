#!/usr/bin/env bash
# A throw-away single-node Slurm (Debian 12's Slurm 22.05) for the workflow's
# cluster test: make slurm-test, tests/test_slurm.py.
#
#   slurm_cluster.sh install      apt-get install slurmctld slurmd munge when missing (root)
#   slurm_cluster.sh start DIR    write DIR/slurm.conf for this host, start munged,
#                                 slurmctld and slurmd; record what was started in DIR
#   slurm_cluster.sh stop DIR     stop exactly the daemons that `start DIR` started
#   slurm_cluster.sh env DIR      print `export SLURM_CONF=...` for clients
# While it runs, /etc/slurm/slurm.conf is a link to DIR/slurm.conf (removed by stop).
#
# `start` does nothing when `sinfo` already answers: an existing cluster is used
# as it is and `stop` leaves it alone. The configuration has no accounting
# database (AccountingStorageType=accounting_storage/none), keeps finished jobs
# in slurmctld's memory for an hour (MinJobAge=3600: squeue and scontrol still
# show them to Snakemake's status checks and to the test), and writes one line
# per finished job to DIR/jobcomp.log (jobcomp/filetxt), Slurm's own record that
# the test checks against. Process tracking and task plug-ins are those that
# need no cgroups (proctrack/linuxproc, task/none), so it runs in a container.
set -euo pipefail

cmd=${1:-}
dir=${2:-}

die() { echo "slurm_cluster: $*" >&2; exit 1; }

need_dir() {
  [ -n "$dir" ] || die "usage: $0 $cmd DIR"
  mkdir -p "$dir"
  dir=$(cd "$dir" && pwd)
}

have_slurm() { command -v slurmctld >/dev/null && command -v slurmd >/dev/null && command -v munged >/dev/null && command -v sbatch >/dev/null; }

cluster_answers() { command -v sinfo >/dev/null && timeout 10 sinfo -h >/dev/null 2>&1; }

do_install() {
  if have_slurm; then echo "slurm_cluster: slurmctld, slurmd, munge installed"; return 0; fi
  [ "$(id -u)" = 0 ] || die "installing Slurm needs root (apt-get install slurmctld slurmd munge)"
  command -v apt-get >/dev/null || die "no apt-get: install slurmctld, slurmd and munge by hand"
  echo "slurm_cluster: installing slurmctld slurmd munge (apt-get)"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  # policy-rc.d: the packages' post-install scripts must not start services
  # (no init system in a container; the test starts its own daemons).
  local prc=/usr/sbin/policy-rc.d made=0
  if [ ! -e $prc ]; then printf '#!/bin/sh\nexit 101\n' >$prc; chmod +x $prc; made=1; fi
  apt-get install -y -qq --no-install-recommends slurmctld slurmd slurm-client munge >/dev/null || { [ $made = 1 ] && rm -f $prc; die "apt-get install failed"; }
  [ $made = 1 ] && rm -f $prc
  have_slurm || die "Slurm still missing after apt-get"
}

wait_for() {  # wait_for SECONDS CMD...: poll until CMD succeeds
  local n=$(($1 * 5)); shift
  for _ in $(seq "$n"); do "$@" >/dev/null 2>&1 && return 0; sleep 0.2; done
  return 1
}

do_start() {
  need_dir
  if cluster_answers; then
    echo "slurm_cluster: sinfo answers; using the running cluster"
    : >"$dir/started"
    return 0
  fi
  have_slurm || die "Slurm is not installed (run: $0 install)"
  : >"$dir/started"
  local host conf=$dir/slurm.conf
  host=$(hostname -s)

  # munge: a key, a socket folder; one daemon unless one already answers
  if ! { command -v munge >/dev/null && munge -n 2>/dev/null | unmunge >/dev/null 2>&1; }; then
    mkdir -p /etc/munge /run/munge /var/lib/munge /var/log/munge
    if [ ! -s /etc/munge/munge.key ]; then
      dd if=/dev/urandom of=/etc/munge/munge.key bs=1024 count=1 status=none
    fi
    local mu=root
    if id munge >/dev/null 2>&1; then mu=munge; fi
    chown "$mu" /etc/munge /etc/munge/munge.key /run/munge /var/lib/munge /var/log/munge
    chmod 700 /etc/munge; chmod 400 /etc/munge/munge.key; chmod 755 /run/munge
    if [ "$mu" = munge ]; then
      runuser -u munge -- munged
    else
      munged --force
    fi
    wait_for 10 sh -c 'munge -n | unmunge' || die "munged did not start"
    cp /run/munge/munged.pid "$dir/munged.pid"
    echo munged >>"$dir/started"
  fi

  # the node as slurmd sees it (CPUs, sockets, cores, memory), reachable on loopback
  local node
  node=$(slurmd -C | head -1)
  mkdir -p "$dir/ctld" "$dir/spool"
  cat >"$conf" <<EOF
# written by tests/slurm/slurm_cluster.sh: single node, no accounting database
ClusterName=brdfpipe-test
SlurmctldHost=$host(127.0.0.1)
AuthType=auth/munge
SlurmUser=root
SlurmdUser=root
StateSaveLocation=$dir/ctld
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/slurmctld.log
SlurmdLogFile=$dir/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/filetxt
JobCompLoc=$dir/jobcomp.log
MpiDefault=none
SwitchType=switch/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
MinJobAge=3600
ReturnToService=2
SlurmctldTimeout=30
SlurmdTimeout=60
$node NodeAddr=127.0.0.1 State=UNKNOWN
# OverSubscribe=FORCE:2: two jobs may share a core. A Slurm job of this workflow
# spends most of its wall time starting Snakemake and waiting to be polled, so
# on a single small node two per core keep the CPUs busy.
PartitionName=debug Nodes=$host Default=YES MaxTime=INFINITE State=UP OverSubscribe=FORCE:2
EOF
  # Clients inside jobs must find the configuration too: the Slurm plug-in's
  # job step drops every SLURM_* variable (SLURM_CONF included) before it calls
  # srun, so the configuration goes where Slurm looks by default.
  local etc=/etc/slurm/slurm.conf
  if [ -e "$etc" ] && [ ! -L "$etc" ]; then
    die "$etc exists but no cluster answers sinfo: start that cluster, or move $etc away"
  fi
  mkdir -p /etc/slurm
  ln -sfn "$conf" "$etc"
  echo conflink >>"$dir/started"
  export SLURM_CONF=$conf
  slurmctld -i
  wait_for 20 scontrol ping || die "slurmctld did not start (see $dir/slurmctld.log)"
  cat "$dir/slurmctld.pid" >"$dir/slurmctld.started.pid"
  echo slurmctld >>"$dir/started"
  slurmd
  wait_for 30 sh -c "sinfo -h -N -o %T | grep -Eq '^(idle|mixed|allocated)'" \
    || die "slurmd did not register (see $dir/slurmd.log)"
  cat "$dir/slurmd.pid" >"$dir/slurmd.started.pid"
  echo slurmd >>"$dir/started"
  echo "slurm_cluster: started $(tr '\n' ' ' <"$dir/started")(SLURM_CONF=$conf)"
}

stop_pid() {  # stop_pid NAME PIDFILE: TERM, then KILL, the one process
  local name=$1 pidf=$2 pid
  [ -s "$pidf" ] || return 0
  pid=$(cat "$pidf")
  if kill -0 "$pid" 2>/dev/null && [ "$(cat /proc/"$pid"/comm 2>/dev/null)" = "$name" ]; then
    kill "$pid" 2>/dev/null || true
    for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    kill -0 "$pid" 2>/dev/null && kill -9 "$pid" 2>/dev/null || true
  fi
}

do_stop() {
  need_dir
  [ -f "$dir/started" ] || return 0
  grep -qx slurmd "$dir/started" && stop_pid slurmd "$dir/slurmd.started.pid"
  grep -qx slurmctld "$dir/started" && stop_pid slurmctld "$dir/slurmctld.started.pid"
  grep -qx munged "$dir/started" && stop_pid munged "$dir/munged.pid"
  if grep -qx conflink "$dir/started" && [ "$(readlink /etc/slurm/slurm.conf)" = "$dir/slurm.conf" ]; then
    rm -f /etc/slurm/slurm.conf
  fi
  rm -f "$dir/started"
  echo "slurm_cluster: stopped the daemons it started"
}

case "$cmd" in
  install) do_install ;;
  start) do_start ;;
  stop) do_stop ;;
  env) need_dir; [ -f "$dir/slurm.conf" ] && echo "export SLURM_CONF=$dir/slurm.conf" || true ;;
  *) die "usage: $0 install|start DIR|stop DIR|env DIR" ;;
esac
