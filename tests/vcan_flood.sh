# Runs inside the vcan sandbox (tests/test_can_flood.py, benchmarks/bench_can.py --vcan): the
# monitor on the real vcan0 while cangen floods the bus at full speed.
#
# Usage: sh tests/vcan_flood.sh OUT_DIR FEED.log SPOOF_HEX [FLOOD_S] [CALM_S] [KINDS]
#   FEED.log   candump log of valid input traffic (six clear channels and TrainState at 10 Hz),
#              replayed by canplayer so that the monitor has a calm baseline (no demand)
#   SPOOF_HEX  8 data bytes sent on 0x010 by the foreign sender (flood 'foreign')
#   FLOOD_S    seconds per flood (default 3), CALM_S calm seconds before and after (default 2)
#   KINDS      floods to run, space separated (default "random channel0 mix foreign")
#
# The monitor runs `python -m railguard run --interface socketcan --channel vcan0 --no-player --unsecured
# --table m1 --duration D --json --no-plot --quiet --out OUT_DIR` and is ended by SIGTERM.
# Writes OUT_DIR/bd.log (candump -L, kernel filter: ID 010 and the heartbeat 7FF), monitor.json,
# monitor.err, started.txt (first BrakeDemand seen), floods.txt (one line per flood: kind t0 t1
# tx_packets_delta rx_packets_delta, vcan0's counters, all senders), and prints monitor_rc=N.
# Exit status: the monitor's.
set -u
OUT=$1
FEED=$2
SPOOF=$3
FLOOD=${4:-3}
CALM=${5:-2}
KINDS=${6:-random channel0 mix foreign}
GAP=1
STATS=/sys/class/net/vcan0/statistics

# cangen at full speed: -g 0 (no gap), -i (ignore ENOBUFS: keep writing when the queue is
# full). The sandbox has one CPU: the flooder competes with the monitor for it at the same
# priority, which is harder than a flooder on another node of a real bus.
flood_args() {
    case $1 in
        random) echo "-g 0 -i" ;;                              # random IDs, lengths, data
        channel0) echo "-g 0 -i -I 020 -L 8" ;;               # a monitored obstacle channel, random data
        mix) echo "-g 0 -i -m" ;;                              # FD, extended and remote frames mixed
        foreign) echo "-g 0 -i -I 010 -L 8 -D $SPOOF" ;;      # a foreign sender on the monitor's own ID
        *) echo "unknown flood $1" >&2; exit 2 ;;
    esac
}

# --duration bounds the run generously; the script ends it with SIGTERM CALM seconds after the
# last flood (the schedule slips when the sandbox is loaded, a fixed duration could end first)
N=0
for k in $KINDS; do N=$((N + 1)); done
DURATION=$(awk "BEGIN { print 2 * ($CALM + $N * ($FLOOD + $GAP) + $CALM) + 30 }")

# candump records ID 010 (the monitor's BrakeDemand; the foreign flood sends there too) and the
# heartbeat 7FF (standard data frames only). The foreign flood outruns it: a 100 MB socket
# buffer holds the backlog and -d reports drops; kernel timestamps are taken on arrival, so a
# backlog does not change the measured gaps.
candump -L -d -r 100000000 vcan0,010:7FF,7FF:C00007FF > "$OUT/bd.log" 2> "$OUT/candump.err" &
CD=$!
# heartbeat: a C program sending every 10 ms. A gap in it means the whole sandbox stalled (its
# host was busy), not the monitor; the test tells such gaps apart.
cangen vcan0 -g 10 -i -I 7FF -L 8 -D 5A5A5A5A5A5A5A5A 2> "$OUT/heartbeat.err" &
HB=$!
canplayer -l i -I "$FEED" > /dev/null 2> "$OUT/canplayer.err" &
CP=$!
python -m railguard run --interface socketcan --channel vcan0 --no-player --unsecured --table m1 --duration "$DURATION" \
    --json --no-plot --quiet --out "$OUT" > "$OUT/monitor.json" 2> "$OUT/monitor.err" &
MON=$!

# the monitor is up once its first BrakeDemand is on the bus (python starts slowly in here)
i=0
while ! grep -q " 010#" "$OUT/bd.log" 2>/dev/null; do
    i=$((i + 1))
    if [ $i -gt 600 ] || ! kill -0 $MON 2>/dev/null; then
        echo "monitor did not start" >&2
        break
    fi
    sleep 0.1
done
date +%s.%N > "$OUT/started.txt"
sleep "$CALM"

: > "$OUT/floods.txt"
for kind in $KINDS; do
    args=$(flood_args "$kind")
    tx0=$(cat $STATS/tx_packets); rx0=$(cat $STATS/rx_packets); t0=$(date +%s.%N)
    cangen vcan0 $args 2>> "$OUT/cangen.err" &
    CG=$!
    sleep "$FLOOD"
    kill $CG
    wait $CG 2>/dev/null
    tx1=$(cat $STATS/tx_packets); rx1=$(cat $STATS/rx_packets); t1=$(date +%s.%N)
    echo "$kind $t0 $t1 $((tx1 - tx0)) $((rx1 - rx0))" >> "$OUT/floods.txt"
    sleep "$GAP"
done
sleep "$CALM"

kill -TERM $MON
i=0
while kill -0 $MON 2>/dev/null && [ $i -lt 300 ]; do i=$((i + 1)); sleep 0.1; done
kill -0 $MON 2>/dev/null && { echo "monitor still running 30 s after SIGTERM: SIGKILL" >&2; kill -KILL $MON; }
wait $MON
MONITOR_RC=$?
kill $CP $HB
# candump may still work through the foreign flood's backlog: stop it once its log stops growing
last=-1
i=0
while [ $i -lt 100 ]; do
    size=$(wc -c < "$OUT/bd.log")
    [ "$size" -eq "$last" ] && break
    last=$size
    i=$((i + 1))
    sleep 0.5
done
kill $CD
wait $CD 2>/dev/null
echo "monitor_rc=$MONITOR_RC"
exit $MONITOR_RC
