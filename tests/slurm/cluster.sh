# tests/slurm/cluster.sh — a throw-away single-node Slurm from Debian's packages (munge, slurmctld, slurmd), all of
# it in one temporary folder: its own munge key and socket, slurm.conf, state, spool, logs and ports; no cgroups
# (proctrack/linuxproc, task/none), no accounting. Sourced by tests/slurm/run:
#
#     slurm_start DIR      # starts munged, slurmctld and slurmd; exports SLURM_CONF; waits for the node to be idle
#     slurm_stop           # scontrol shutdown, then kills whatever is left of the three by pid; safe to call twice
#
# Needs root (slurmd runs jobs as their user) and nothing listening on the two ports it picks.

slurm_free_port() {
    local p
    for p in $(shuf -i 20000-40000 -n 40); do
        ! (exec 3<>/dev/tcp/127.0.0.1/$p) 2>/dev/null && { echo "$p"; return 0; }
    done
    return 1
}

slurm_start() {
    SLURM_DIR=$1
    mkdir -p "$SLURM_DIR"/{state,spool,log,munge}
    chmod 700 "$SLURM_DIR/munge"
    # munge: a fresh key, its own socket; -f: munged refuses root-owned setups without it
    dd if=/dev/urandom of="$SLURM_DIR/munge/munge.key" bs=1024 count=1 status=none
    chmod 400 "$SLURM_DIR/munge/munge.key"
    munged -f --key-file="$SLURM_DIR/munge/munge.key" --socket="$SLURM_DIR/munge/munge.sock" \
        --pid-file="$SLURM_DIR/munge/munged.pid" --log-file="$SLURM_DIR/log/munged.log" \
        --seed-file="$SLURM_DIR/munge/munged.seed" || return 1
    local ctld_port slurmd_port cpus mem
    ctld_port=$(slurm_free_port) && slurmd_port=$(slurm_free_port) || return 1
    cpus=$(nproc)
    mem=$(awk '/MemTotal/ { printf "%d", $2 / 1024 * 0.8 }' /proc/meminfo)
    cat > "$SLURM_DIR/slurm.conf" <<CONF
ClusterName=scicaptest
SlurmctldHost=localhost(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$SLURM_DIR/munge/munge.sock
StateSaveLocation=$SLURM_DIR/state
SlurmdSpoolDir=$SLURM_DIR/spool
SlurmctldPidFile=$SLURM_DIR/slurmctld.pid
SlurmdPidFile=$SLURM_DIR/slurmd.pid
SlurmctldLogFile=$SLURM_DIR/log/slurmctld.log
SlurmdLogFile=$SLURM_DIR/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MpiDefault=none
SwitchType=switch/none
ReturnToService=2
SchedulerType=sched/backfill
SchedulerParameters=sched_interval=1
MinJobAge=300
InactiveLimit=0
KillWait=5
NodeName=scicapnode NodeHostname=localhost NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=scicap Nodes=scicapnode Default=YES MaxTime=INFINITE State=UP
CONF
    export SLURM_CONF=$SLURM_DIR/slurm.conf
    slurmctld -i -f "$SLURM_CONF" || return 1
    slurmd -N scicapnode -f "$SLURM_CONF" || return 1
    local i
    for i in $(seq 60); do
        sinfo -h -o '%t' 2>/dev/null | grep -qx 'idle' && return 0
        sleep 0.5
    done
    echo "slurm: the node did not come up idle within 30 s:" >&2
    sinfo >&2 || true
    tail -n 20 "$SLURM_DIR/log/slurmctld.log" "$SLURM_DIR/log/slurmd.log" >&2 || true
    return 1
}

slurm_stop() {
    [ -n "${SLURM_DIR:-}" ] || return 0
    scontrol shutdown >/dev/null 2>&1 || true
    local f pid i
    for f in slurmd.pid slurmctld.pid munge/munged.pid; do
        pid=$(cat "$SLURM_DIR/$f" 2>/dev/null) || continue
        for i in $(seq 50); do  # 10 s for a clean stop, SIGTERM after 4 s
            kill -0 "$pid" 2>/dev/null || break
            [ "$i" = 20 ] && kill "$pid" 2>/dev/null
            sleep 0.2
        done
        kill -9 "$pid" 2>/dev/null || true
    done
}
